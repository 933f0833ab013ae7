//! Running every method of one triplet: trained runs (learned and heuristic blends), the sweep,
//! the oracle and the nearest input view, each timed.

use super::*;

/// A blended view of a trained run: the shared time split plus this blend's time.
pub(super) fn blended(
    method: &str,
    normals: usize,
    planes: usize,
    b: Blended,
    base: Times,
) -> Output {
    Output {
        method: method.into(),
        normals,
        planes,
        image: b.image,
        times: Times {
            blend_ms: b.blend_ms,
            ..base
        },
        exact: Vec::new(),
    }
}

/// What every method of one evaluation shares.
pub(super) struct Ctx<'a> {
    pub(super) a: &'a EvalArgs,
    pub(super) models: &'a [Loaded],
    pub(super) sweep_grid: &'a [(usize, usize)],
    pub(super) oracle_grid: &'a [(usize, usize)],
    pub(super) sweep_config: SweepConfig,
}

impl Ctx<'_> {
    fn wants(&self, m: Method) -> bool {
        self.a.methods.contains(&m)
    }

    /// Every method's view of `tf` from the pair (`rf`, `sf`), timed from the decoded images.
    pub(super) fn run_methods(
        &self,
        rf: &LoadedFrame,
        sf: &LoadedFrame,
        tf: &LoadedFrame,
        seq: &mhi_data::Sequence,
    ) -> anyhow::Result<Vec<Output>> {
        let mut out = Vec::new();
        if self.wants(Method::Nearest) {
            out.push(nearest(rf, sf, tf));
        }
        for m in self.models {
            self.model_methods(m, (rf, sf, tf), &mut out)?;
        }
        self.sweep_methods((rf, sf, tf), &mut out)?;
        self.oracle_methods((rf, sf, tf), seq, &mut out)?;
        Ok(out)
    }

    /// A trained run's methods (learned, the heuristic blends of its stage 1, or the MPI).
    fn model_methods(
        &self,
        m: &Loaded,
        (rf, sf, tf): (&LoadedFrame, &LoadedFrame, &LoadedFrame),
        out: &mut Vec<Output>,
    ) -> anyhow::Result<()> {
        let a = self.a;
        let model = &m.model;
        let n = model.normals().len();
        let is_mpi = n == 1;
        if is_mpi && !self.wants(Method::Mpi) {
            return Ok(());
        }
        let heuristics = [
            (Method::Soft, "soft", BlendHeuristic::Soft),
            (Method::Hard, "hard", BlendHeuristic::Hard),
            (Method::Avg, "avg", BlendHeuristic::Avg),
        ];
        if !is_mpi
            && !self.wants(Method::Learned)
            && !self.wants(Method::Consistent)
            && !heuristics.iter().any(|h| self.wants(h.0))
        {
            return Ok(());
        }
        let d = model.depths().len();
        let synth = ViewSynthesis::new(MhiSource::Learned(model));
        let (mhi, t) = synth.mhi(rf, sf)?;
        let inference = Times {
            volume_ms: t.volume_ms,
            network_ms: t.network_ms,
            ..Times::default()
        };
        // The Soft blend needs no multi-normal images: it is rendered as the sweep's is,
        // its blend bounded within the budget (light normals leave out more) and, for the
        // pruned-against-exact table, exactly too.
        let soft = |out: &mut Vec<Output>| -> anyhow::Result<()> {
            let (image, render_ms, exact) = render_soft(&mhi, tf, a)?;
            out.push(Output {
                method: "soft".into(),
                normals: n,
                planes: d,
                image,
                times: Times {
                    render_ms,
                    ..inference
                },
                exact,
            });
            Ok(())
        };
        let from_images = [
            Method::Learned,
            Method::Hard,
            Method::Avg,
            Method::Consistent,
        ];
        if !is_mpi && !from_images.iter().any(|m| self.wants(*m)) {
            soft(out)?;
            return Ok(());
        }
        // The learned blend reads the multi-normal images (each within the budget on its
        // own); Hard and Avg blend the same images.
        let mn = multi_normal(&mhi, &tf.camera, a.prune())?;
        let base = Times {
            render_ms: mn.render_ms,
            ..inference
        };
        if is_mpi {
            out.push(Output {
                method: "mpi".into(),
                normals: 1,
                planes: d,
                image: mn.images[0].clone(),
                times: base,
                exact: Vec::new(),
            });
            return Ok(());
        }
        let blend = |choice| mn.blend(&mhi, Some(model), &tf.camera, choice);
        // Each normal's photo-inconsistency, for the consistent blend and for a blending
        // network that reads it (timed as part of each blend).
        let reads_inc = self.wants(Method::Learned) && model.blend_consistency().is_some();
        let inc = (self.wants(Method::Consistent) || reads_inc)
            .then(|| -> anyhow::Result<_> {
                let t0 = Instant::now();
                let inc = mhi_net::inconsistency(&mhi, rf, sf, &tf.camera)?;
                Ok((inc, t0.elapsed().as_secs_f64() * 1e3))
            })
            .transpose()?;
        if self.wants(Method::Learned) {
            let b = match &inc {
                Some((images, c_ms)) if reads_inc => {
                    let mut b = mn.blend_learned_with(&mhi, model, &tf.camera, images)?;
                    b.blend_ms += c_ms;
                    b
                }
                _ => blend(BlendChoice::Learned)?,
            };
            out.push(blended("learned", n, d, b, base));
        }
        if let (true, Some((images, c_ms))) = (self.wants(Method::Consistent), &inc) {
            let mut b = mn.blend_consistent(&mhi, &tf.camera, images, a.consistency_beta)?;
            b.blend_ms += c_ms;
            out.push(blended("consistent", n, d, b, base));
        }
        for (which, name, h) in heuristics {
            if !self.wants(which) {
                continue;
            }
            if which == Method::Soft {
                soft(out)?;
                continue;
            }
            let b = blend(BlendChoice::Heuristic(h))?;
            out.push(blended(name, n, d, b, base));
        }
        Ok(())
    }

    /// The training-free sweep at every --sweep-grid size.
    fn sweep_methods(
        &self,
        (rf, sf, tf): (&LoadedFrame, &LoadedFrame, &LoadedFrame),
        out: &mut Vec<Output>,
    ) -> anyhow::Result<()> {
        let a = self.a;
        let made = |source: MhiSource<'_>| ViewSynthesis::new(source).mhi(rf, sf);
        for &(n, d) in self.sweep_grid {
            let (mhi, t) = made(MhiSource::Sweep {
                normals: NormalSet::paper_subset(n)?,
                depths: a.range.depths(d)?,
                // The window is given at the tuned short side and scaled to this image, as the
                // learned models' sweep prior and `render` scale it: the sweep row is what an
                // untrained residual model renders, at any evaluation size.
                config: self
                    .sweep_config
                    .scaled_to_short_side(rf.image.width().min(rf.image.height())),
            })?;
            let (image, render_ms, exact) = render_soft(&mhi, tf, a)?;
            out.push(Output {
                method: "sweep".into(),
                normals: n,
                planes: d,
                image,
                times: Times {
                    volume_ms: t.volume_ms,
                    network_ms: 0.0,
                    render_ms,
                    blend_ms: 0.0,
                },
                exact,
            });
        }
        Ok(())
    }

    /// The MHI of the scene's exact geometry at every --oracle-grid size (synthetic scenes).
    fn oracle_methods(
        &self,
        (rf, sf, tf): (&LoadedFrame, &LoadedFrame, &LoadedFrame),
        seq: &mhi_data::Sequence,
        out: &mut Vec<Output>,
    ) -> anyhow::Result<()> {
        let a = self.a;
        let made = |source: MhiSource<'_>| ViewSynthesis::new(source).mhi(rf, sf);
        if !self.oracle_grid.is_empty() {
            let scene = load_scene(&seq.dir().join("scene.json"))?;
            let truth = crate::support::truth_of(&scene, &rf.camera);
            for &(n, d) in self.oracle_grid {
                let (mhi, _) = made(MhiSource::Oracle {
                    normals: NormalSet::paper_subset(n)?,
                    depths: a.range.depths(d)?,
                    truth: &truth,
                })?;
                let (image, render_ms, exact) = render_soft(&mhi, tf, a)?;
                out.push(Output {
                    method: "oracle".into(),
                    normals: n,
                    planes: d,
                    image,
                    times: Times {
                        render_ms,
                        ..Times::default()
                    },
                    exact,
                });
            }
        }
        Ok(())
    }
}

/// The input view nearest the target, as it is.
fn nearest(rf: &LoadedFrame, sf: &LoadedFrame, tf: &LoadedFrame) -> Output {
    let t0 = Instant::now();
    let image = crate::methods::nearest_input(rf, sf, &tf.camera)
        .image
        .clone();
    Output {
        method: "nearest".into(),
        normals: 0,
        planes: 0,
        image,
        times: Times {
            blend_ms: ms(t0),
            ..Times::default()
        },
        exact: Vec::new(),
    }
}

/// Render with Soft blending within --budget (timed) and, for the pruned-vs-exact table, also
/// exactly (timed, alternately) when something may be left out, and within each of
/// --also-budgets. Returns the image to score (within --budget), its render time and the
/// checks.
pub(super) fn render_soft(
    mhi: &Mhi,
    tf: &LoadedFrame,
    a: &EvalArgs,
) -> anyhow::Result<(Rgb32FImage, f64, Vec<ExactCheck>)> {
    let go = |p: Prune| -> anyhow::Result<(mhi_render::Rendered, f64)> {
        let t0 = Instant::now();
        let r = render(
            mhi,
            &tf.camera,
            &RenderOptions {
                blend: Blend::Heuristic(BlendHeuristic::Soft),
                prune: p,
                keep_multi_normal: false,
            },
        )?;
        Ok((r, ms(t0)))
    };
    // --budget first (its pruned render is the scored image; under --exact the exact one is),
    // then --also-budgets, each against its own exact render.
    let mut scored = None;
    let mut checks = Vec::new();
    for b in a.measured_budgets() {
        let prune = Prune::with_budget(b / 255.0);
        let ((exact, exact_ms), (pruned, pruned_ms)) = paired(|| go(Prune::NONE), || go(prune))?;
        let own = if scored.is_none() && a.prune().budget > 0.0 {
            scored = Some((pruned.image, pruned_ms));
            None
        } else {
            Some((pruned.image, pruned_ms))
        };
        checks.push(ExactCheck {
            budget: b,
            pruned: own,
            needed: mhi_render::needed_share(mhi, &tf.camera, &exact.weights, prune.budget)?,
            image: exact.image,
            render_ms: exact_ms,
            stats: pruned.stats,
        });
    }
    let (image, image_ms) = match scored {
        Some(s) => s,
        None => {
            let (exact, exact_ms) = go(Prune::NONE)?;
            (exact.image, exact_ms)
        }
    };
    Ok((image, image_ms, checks))
}

/// Renders of one MHI and view timed exactly and pruned, alternately, this many times each: a
/// shared machine's swings then hit both alike, and the medians are reported.
pub(super) const PAIRED_RUNS: usize = 3;

/// Run `exact` and `pruned` (each giving its result and milliseconds) alternately
/// [`PAIRED_RUNS`] times; their first results with the median times.
pub(super) fn paired<T>(
    mut exact: impl FnMut() -> anyhow::Result<(T, f64)>,
    mut pruned: impl FnMut() -> anyhow::Result<(T, f64)>,
) -> anyhow::Result<((T, f64), (T, f64))> {
    let (mut first_e, mut first_p) = (None, None);
    let (mut te, mut tp) = (Vec::new(), Vec::new());
    for _ in 0..PAIRED_RUNS {
        let (e, ms_e) = exact()?;
        let (p, ms_p) = pruned()?;
        te.push(ms_e);
        tp.push(ms_p);
        first_e.get_or_insert(e);
        first_p.get_or_insert(p);
    }
    let median = crate::support::median;
    let (e, p) = (
        first_e.context("no exact render")?,
        first_p.context("no pruned render")?,
    );
    Ok(((e, median(te)), (p, median(tp))))
}
