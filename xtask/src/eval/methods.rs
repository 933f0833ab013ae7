//! Running every method of one triplet: trained runs (learned and heuristic blends), the sweep,
//! the oracle and the nearest input view, each timed.

use super::*;

/// A blended view of a trained run: the shared time split plus this blend's time since `t0`.
pub(super) fn blended(
    method: &str,
    normals: usize,
    planes: usize,
    image: Rgb32FImage,
    base: Times,
    t0: Instant,
) -> Output {
    Output {
        method: method.into(),
        normals,
        planes,
        image,
        times: Times {
            blend_ms: ms(t0),
            ..base
        },
        exact: None,
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
        let a = self.a;
        let mut out = Vec::new();
        if self.wants(Method::Nearest) {
            let t0 = Instant::now();
            let c = tf.camera.center_in_world();
            let dr = (rf.camera.center_in_world() - c).length();
            let ds_ = (sf.camera.center_in_world() - c).length();
            let image = if dr <= ds_ {
                rf.image.clone()
            } else {
                sf.image.clone()
            };
            out.push(Output {
                method: "nearest".into(),
                normals: 0,
                planes: 0,
                image,
                times: Times {
                    blend_ms: ms(t0),
                    ..Times::default()
                },
                exact: None,
            });
        }
        for m in self.models {
            let model = &m.model;
            let n = model.normals().len();
            let is_mpi = n == 1;
            if is_mpi && !self.wants(Method::Mpi) {
                continue;
            }
            let heuristics = [
                (Method::Soft, "soft", BlendHeuristic::Soft),
                (Method::Hard, "hard", BlendHeuristic::Hard),
                (Method::Avg, "avg", BlendHeuristic::Avg),
            ];
            if !is_mpi
                && !self.wants(Method::Learned)
                && !heuristics.iter().any(|h| self.wants(h.0))
            {
                continue;
            }
            let d = model.depths().len();
            let t0 = Instant::now();
            let volume = model.stage1_input(rf, sf)?;
            let volume_ms = ms(t0);
            let t1 = Instant::now();
            let alphas = model.alphas(volume)?;
            let network_ms = ms(t1);
            let t2 = Instant::now();
            let mhi = model.mhi(rf, alphas)?;
            let r = render_mni(&mhi, &tf.camera, a.prune())?;
            let render_ms = ms(t2);
            let base = Times {
                volume_ms,
                network_ms,
                render_ms,
                blend_ms: 0.0,
            };
            if is_mpi {
                out.push(Output {
                    method: "mpi".into(),
                    normals: 1,
                    planes: d,
                    image: r.multi_normal[0].clone(),
                    times: base,
                    exact: None,
                });
                continue;
            }
            let mni = &r.multi_normal;
            if self.wants(Method::Learned) {
                let t3 = Instant::now();
                let soft = heuristic_weights_for(
                    model.normals(),
                    &rf.camera,
                    &tf.camera,
                    BlendHeuristic::Soft,
                );
                let w = model.blend_weights(mni, &soft)?;
                out.push(blended("learned", n, d, combine(mni, &w), base, t3));
            }
            for (which, name, h) in heuristics {
                if !self.wants(which) {
                    continue;
                }
                let t3 = Instant::now();
                let w = heuristic_weights_for(model.normals(), &rf.camera, &tf.camera, h);
                let mut o = blended(name, n, d, combine(mni, &w), base, t3);
                if which == Method::Soft && a.prune().budget > 0.0 {
                    // The same MHI's multi-normal images rendered exactly, Soft-blended.
                    let t4 = Instant::now();
                    let e = render_mni(&mhi, &tf.camera, Prune::NONE)?;
                    let render_ms = ms(t4);
                    o.exact = Some(ExactCheck {
                        image: combine(&e.multi_normal, &w),
                        render_ms,
                        stats: r.stats,
                    });
                }
                out.push(o);
            }
        }
        for &(n, d) in self.sweep_grid {
            let normals = NormalSet::paper_subset(n)?;
            let depths = depths_linear_in_disparity(a.near, a.far, d)?;
            let t0 = Instant::now();
            let mhi = sweep_mhi(
                &normals,
                &depths,
                &rf.camera,
                &rf.image,
                &sf.camera,
                &sf.image,
                &self.sweep_config,
            )?;
            let volume_ms = ms(t0);
            let (image, render_ms, exact) = render_soft(&mhi, tf, a.prune())?;
            out.push(Output {
                method: "sweep".into(),
                normals: n,
                planes: d,
                image,
                times: Times {
                    volume_ms,
                    network_ms: 0.0,
                    render_ms,
                    blend_ms: 0.0,
                },
                exact,
            });
        }
        if !self.oracle_grid.is_empty() {
            let scene = load_scene(&seq.dir().join("scene.json"))?;
            let truth = crate::experiments::truth_of(&scene, &rf.camera);
            for &(n, d) in self.oracle_grid {
                let normals = NormalSet::paper_subset(n)?;
                let depths = depths_linear_in_disparity(a.near, a.far, d)?;
                let alpha = oracle_alpha(&normals, &depths, &rf.camera, &truth);
                let mhi = Mhi::new(
                    normals,
                    depths,
                    rf.camera,
                    LayerColor::Shared(rf.image.clone()),
                    alpha,
                )?;
                let (image, render_ms, exact) = render_soft(&mhi, tf, a.prune())?;
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
        Ok(out)
    }
}

/// Render with Soft blending within `prune` (timed) and, when something may be left out, also
/// exactly (timed) for the pruned-vs-exact table. Returns the image to score (the pruned one),
/// its render time and the exact check.
pub(super) fn render_soft(
    mhi: &Mhi,
    tf: &LoadedFrame,
    prune: Prune,
) -> anyhow::Result<(Rgb32FImage, f64, Option<ExactCheck>)> {
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
    let (exact, exact_ms) = go(Prune::NONE)?;
    if prune.budget <= 0.0 {
        return Ok((exact.image, exact_ms, None));
    }
    let (pruned, pruned_ms) = go(prune)?;
    Ok((
        pruned.image,
        pruned_ms,
        Some(ExactCheck {
            image: exact.image,
            render_ms: exact_ms,
            stats: pruned.stats,
        }),
    ))
}
