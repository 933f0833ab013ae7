//! View synthesis as one capability: make an MHI from a posed pair (a trained model, the
//! training-free sweep or, for synthetic scenes, the exact geometry), then render any target view
//! of it with a blend choice and an error budget, getting the image, the multi-normal images, the
//! weights and the time split. [`multi_normal`] renders a view's multi-normal images once for
//! several blends.

use std::time::Instant;

use image::Rgb32FImage;
use mhi_data::LoadedFrame;
use mhi_geom::{BlendHeuristic, Camera, NormalSet};
use mhi_render::{
    Blend, LayerColor, Mhi, PixelTruth, Prune, RenderOptions, RenderStats, SweepConfig, combine,
    consistent_weights, heuristic_weights_for, inconsistency_mhi, oracle_alpha, render, sweep_mhi,
};

use crate::Model;

/// Where an MHI comes from.
pub enum MhiSource<'a> {
    /// A trained model: its normals, planes and networks.
    Learned(&'a Model),
    /// The training-free plane sweep with these normals, plane depths (far first) and constants.
    Sweep {
        /// The normals.
        normals: NormalSet,
        /// Plane depths, far first.
        depths: Vec<f64>,
        /// The sweep's constants (see [`SweepConfig::for_short_side`]).
        config: SweepConfig,
    },
    /// Alphas from the exact geometry of a synthetic scene (what the reference camera sees at
    /// each pixel): the best an MHI of these planes can do. The source view is not used.
    Oracle {
        /// The normals.
        normals: NormalSet,
        /// Plane depths, far first.
        depths: Vec<f64>,
        /// Per reference pixel (row-major), the surface it sees, if any.
        truth: &'a [Option<PixelTruth>],
    },
}

/// How the multi-normal images of a view are blended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BlendChoice {
    /// The model's blending network (the Soft heuristic for a sweep MHI, which has none).
    Learned,
    /// A heuristic of the angle between each normal and the pixel's ray (paper Eq. 4).
    Heuristic(BlendHeuristic),
}

/// Time of making an MHI, in milliseconds.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct MhiTimes {
    /// Plane-sweep volume (and, for the sweep, its alphas and the MHI; for the oracle, the MHI
    /// from the ground truth).
    pub volume_ms: f64,
    /// Stage 1 and building its MHI (0 for the sweep and the oracle).
    pub network_ms: f64,
}

/// One synthesised view.
#[derive(Debug, Clone)]
pub struct View {
    /// The blended view, colours in [0, 1] (not clipped).
    pub image: Rgb32FImage,
    /// The N multi-normal images.
    pub multi_normal: Vec<Rgb32FImage>,
    /// The blend weights, `N × H × W`, normalised per pixel.
    pub weights: Vec<f32>,
    /// What the render left out and the bound it kept.
    pub stats: RenderStats,
    /// Warp and composite.
    pub render_ms: f64,
    /// Blend weights and blending.
    pub blend_ms: f64,
}

/// View synthesis from posed pairs.
pub struct ViewSynthesis<'a> {
    source: MhiSource<'a>,
}

impl<'a> ViewSynthesis<'a> {
    /// Synthesis from `source`.
    pub fn new(source: MhiSource<'a>) -> Self {
        Self { source }
    }

    /// The trained model, if the MHIs come from one.
    pub fn model(&self) -> Option<&'a Model> {
        match &self.source {
            MhiSource::Learned(m) => Some(*m),
            MhiSource::Sweep { .. } | MhiSource::Oracle { .. } => None,
        }
    }

    /// The MHI of a posed pair, on the reference frame's grid.
    pub fn mhi(
        &self,
        reference: &LoadedFrame,
        source: &LoadedFrame,
    ) -> crate::Result<(Mhi, MhiTimes)> {
        let t0 = Instant::now();
        let mhi = match &self.source {
            MhiSource::Learned(m) => {
                let input = m.stage1_input(reference, source)?;
                let volume_ms = ms(t0);
                let t1 = Instant::now();
                let (alphas, colours) = m.layers(input)?;
                let mhi = m.mhi_with(reference, alphas, colours)?;
                return Ok((
                    mhi,
                    MhiTimes {
                        volume_ms,
                        network_ms: ms(t1),
                    },
                ));
            }
            MhiSource::Sweep {
                normals,
                depths,
                config,
            } => sweep_mhi(
                normals,
                depths,
                &reference.camera,
                &reference.image,
                &source.camera,
                &source.image,
                config,
            )?,
            MhiSource::Oracle {
                normals,
                depths,
                truth,
            } => {
                let px = reference.image.width() as usize * reference.image.height() as usize;
                if truth.len() != px {
                    return Err(crate::Error::Config(format!(
                        "oracle: {} pixels of ground truth for a {}x{} reference",
                        truth.len(),
                        reference.image.width(),
                        reference.image.height()
                    )));
                }
                Mhi::new(
                    normals.clone(),
                    depths.clone(),
                    reference.camera,
                    LayerColor::Shared(reference.image.clone()),
                    oracle_alpha(normals, depths, &reference.camera, truth),
                )?
            }
        };
        // Without a network, making the MHI is all "volume" time.
        Ok((
            mhi,
            MhiTimes {
                volume_ms: ms(t0),
                network_ms: 0.0,
            },
        ))
    }

    /// Render `mhi` from `target` within `prune`'s budget (see [`render_view`]).
    pub fn render(
        &self,
        mhi: &Mhi,
        target: &Camera,
        blend: BlendChoice,
        prune: Prune,
    ) -> crate::Result<View> {
        render_view(mhi, self.model(), target, blend, prune)
    }
}

/// Render `mhi` from `target` within `prune`'s budget, blended by `model`'s network
/// ([`BlendChoice::Learned`] with a model and N > 1) or a heuristic (Soft when the learned blend
/// is asked of an MHI without a model). A heuristic blend lets the render also leave out normals
/// the view does not need; the learned blend needs every multi-normal image first, so only
/// layers and opaque pixels are left out for it.
pub fn render_view(
    mhi: &Mhi,
    model: Option<&Model>,
    target: &Camera,
    blend: BlendChoice,
    prune: Prune,
) -> crate::Result<View> {
    render_view_keeping(mhi, model, target, blend, prune, true)
}

/// [`render_view`] for when only the blended image is wanted (`render`, orbits): a heuristic
/// blend then does not keep the multi-normal images (the view's `multi_normal` is empty), and
/// its render bounds the blend alone, so each pixel's light normals stop compositing early
/// (see [`mhi_render::Prune`]); same bound, fewer samples. The learned blend needs every
/// multi-normal image and renders as in [`render_view`].
pub fn render_image(
    mhi: &Mhi,
    model: Option<&Model>,
    target: &Camera,
    blend: BlendChoice,
    prune: Prune,
) -> crate::Result<View> {
    render_view_keeping(mhi, model, target, blend, prune, false)
}

fn render_view_keeping(
    mhi: &Mhi,
    model: Option<&Model>,
    target: &Camera,
    blend: BlendChoice,
    prune: Prune,
    keep: bool,
) -> crate::Result<View> {
    let model = model.filter(|_| mhi.n() > 1);
    match (blend, model) {
        (BlendChoice::Learned, Some(m)) => {
            let mn = multi_normal(mhi, target, prune)?;
            let b = mn.blend(mhi, Some(m), target, BlendChoice::Learned)?;
            Ok(View {
                image: b.image,
                multi_normal: mn.images,
                weights: b.weights,
                stats: mn.stats,
                render_ms: mn.render_ms,
                blend_ms: b.blend_ms,
            })
        }
        (choice, _) => {
            let h = match choice {
                BlendChoice::Heuristic(h) => h,
                BlendChoice::Learned => BlendHeuristic::Soft,
            };
            let t0 = Instant::now();
            let r = render(
                mhi,
                target,
                &RenderOptions {
                    blend: Blend::Heuristic(h),
                    prune,
                    keep_multi_normal: keep,
                },
            )?;
            Ok(View {
                image: r.image,
                multi_normal: r.multi_normal,
                weights: r.weights,
                stats: r.stats,
                render_ms: ms(t0),
                blend_ms: 0.0,
            })
        }
    }
}

/// The multi-normal images of one view, rendered once and blended any number of ways.
#[derive(Debug, Clone)]
pub struct MultiNormal {
    /// The N multi-normal images, colours in [0, 1] (not clipped).
    pub images: Vec<Rgb32FImage>,
    /// What the render left out and the bound it kept (every image within it).
    pub stats: RenderStats,
    /// Warp and composite.
    pub render_ms: f64,
}

/// One blend of a view's multi-normal images.
#[derive(Debug, Clone)]
pub struct Blended {
    /// The blended view.
    pub image: Rgb32FImage,
    /// The blend weights, `N × H × W`, normalised per pixel.
    pub weights: Vec<f32>,
    /// Blend weights and blending.
    pub blend_ms: f64,
}

/// The N multi-normal images of `mhi` seen from `target`, within `prune`'s budget: layers are
/// skipped and compositing stops within it (Avg weights at render time never drop a normal, so
/// every image is there for any blend that follows; each image moves by at most the budget,
/// and so does any blend of them).
pub fn multi_normal(mhi: &Mhi, target: &Camera, prune: Prune) -> crate::Result<MultiNormal> {
    let t0 = Instant::now();
    let r = render(
        mhi,
        target,
        &RenderOptions {
            blend: Blend::Heuristic(BlendHeuristic::Avg),
            prune,
            keep_multi_normal: true,
        },
    )?;
    Ok(MultiNormal {
        images: r.multi_normal,
        stats: r.stats,
        render_ms: ms(t0),
    })
}

impl MultiNormal {
    /// Blend the images for `target` (the view they were rendered for): by `model`'s network
    /// ([`BlendChoice::Learned`] with a model and N > 1), else by a heuristic (Soft when the
    /// learned blend is asked without a model).
    pub fn blend(
        &self,
        mhi: &Mhi,
        model: Option<&Model>,
        target: &Camera,
        choice: BlendChoice,
    ) -> crate::Result<Blended> {
        let t0 = Instant::now();
        let heuristic = |h| heuristic_weights_for(mhi.normals(), mhi.reference(), target, h);
        let weights = match (choice, model.filter(|_| mhi.n() > 1)) {
            (BlendChoice::Learned, Some(m)) => {
                m.blend_weights(&self.images, &heuristic(BlendHeuristic::Soft), None)?
            }
            (BlendChoice::Learned, None) => heuristic(BlendHeuristic::Soft),
            (BlendChoice::Heuristic(h), _) => heuristic(h),
        };
        let image = combine(&self.images, &weights);
        Ok(Blended {
            image,
            weights,
            blend_ms: ms(t0),
        })
    }
}

/// The strength β of the consistent blend ([`MultiNormal::blend_consistent`]) when none is
/// given, chosen on validation data (`docs/EXPERIMENTS.md`).
pub const CONSISTENCY_BETA: f32 = 20.0;

/// Per normal, the photo-inconsistency of its geometry along each ray of `target`: the
/// multi-normal images of [`inconsistency_mhi`] (the source photo warped onto every layer, its
/// distance from the reference photo, composited with the MHI's alphas), rendered exactly: they
/// set the blend weights, so a budget spent on them would move the weights by more than it
/// bounds. `reference` and `source` are the pair the MHI was made from. For many views of one
/// pair, [`Consistency`] builds the layers once.
///
/// # Errors
/// If the reference frame is not the MHI's size, or the render fails.
pub fn inconsistency(
    mhi: &Mhi,
    reference: &LoadedFrame,
    source: &LoadedFrame,
    target: &Camera,
) -> crate::Result<Vec<Rgb32FImage>> {
    let inc = inconsistency_mhi(mhi, &reference.image, &source.image, &source.camera)?;
    Ok(multi_normal(&inc, target, Prune::NONE)?.images)
}

/// The consistent blend of one pair's MHI, ready for any number of views: its inconsistency
/// layers ([`inconsistency_mhi`], as large as the MHI) and the strength β.
pub struct Consistency {
    inconsistency: Mhi,
    beta: f32,
}

impl Consistency {
    /// The inconsistency layers of `mhi`, made from `reference` and `source`, blended with
    /// strength `beta` ([`CONSISTENCY_BETA`] is the validated default).
    ///
    /// # Errors
    /// If β is negative or not finite, or the reference frame is not the MHI's size.
    pub fn new(
        mhi: &Mhi,
        reference: &LoadedFrame,
        source: &LoadedFrame,
        beta: f32,
    ) -> crate::Result<Self> {
        mhi_render::check_beta(beta)?;
        Ok(Self {
            inconsistency: inconsistency_mhi(mhi, &reference.image, &source.image, &source.camera)?,
            beta,
        })
    }

    /// `mhi` (the MHI this was built for) seen from `target`, blended consistently: its
    /// multi-normal images within `prune`'s budget, so the blend is too, and the inconsistency
    /// images that set the weights exactly (see [`inconsistency`]).
    ///
    /// # Errors
    /// If `mhi` is not the MHI this was built for, or the render fails.
    pub fn render(&self, mhi: &Mhi, target: &Camera, prune: Prune) -> crate::Result<View> {
        self.render_with(mhi, None, target, prune)
    }

    /// As [`Self::render`], blended by `model`'s network when it reads each normal's
    /// photo-inconsistency ([`Model::blend_consistency`]), else consistently.
    ///
    /// # Errors
    /// As [`Self::render`].
    pub fn render_with(
        &self,
        mhi: &Mhi,
        model: Option<&Model>,
        target: &Camera,
        prune: Prune,
    ) -> crate::Result<View> {
        if mhi.alpha().len() != self.inconsistency.alpha().len()
            || mhi.n() != self.inconsistency.n()
        {
            return Err(crate::Error::Config(
                "the consistent blend was built for another MHI".into(),
            ));
        }
        let mn = multi_normal(mhi, target, prune)?;
        let t0 = Instant::now();
        let inc = multi_normal(&self.inconsistency, target, Prune::NONE)?;
        let inc_ms = ms(t0);
        let b = match model.filter(|m| m.blend_consistency().is_some() && mhi.n() > 1) {
            Some(m) => mn.blend_learned_with(mhi, m, target, &inc.images)?,
            None => mn.blend_consistent(mhi, target, &inc.images, self.beta)?,
        };
        let stats = mn.stats;
        Ok(View {
            image: b.image,
            multi_normal: mn.images,
            weights: b.weights,
            stats,
            render_ms: mn.render_ms,
            blend_ms: b.blend_ms + inc_ms,
        })
    }
}

impl MultiNormal {
    /// Blend the images for `target` by `model`'s blending network, one that reads each
    /// normal's photo-inconsistency (`inconsistency`, [`inconsistency`] for the same view).
    ///
    /// # Errors
    /// If the images do not match or the network fails.
    pub fn blend_learned_with(
        &self,
        mhi: &Mhi,
        model: &Model,
        target: &Camera,
        inconsistency: &[Rgb32FImage],
    ) -> crate::Result<Blended> {
        self.blend_from_soft(mhi, target, |soft| {
            model.blend_weights(&self.images, soft, Some(inconsistency))
        })
    }

    /// Blend the images for `target` by Soft weights leaning towards the normals whose geometry
    /// both photos agree with: `soft_k · exp(−β · c_k)`, with `c_k` the mean over RGB of
    /// `inconsistency[k]` ([`inconsistency`] for the same view); see
    /// [`mhi_render::consistent_weights`]. Needs no training.
    ///
    /// # Errors
    /// If β is negative or not finite, or the images do not match.
    pub fn blend_consistent(
        &self,
        mhi: &Mhi,
        target: &Camera,
        inconsistency: &[Rgb32FImage],
        beta: f32,
    ) -> crate::Result<Blended> {
        self.blend_from_soft(mhi, target, |soft| {
            Ok(consistent_weights(soft, inconsistency, beta)?)
        })
    }

    /// The images blended by `weights_of(Soft's weights for target)`, timed.
    fn blend_from_soft(
        &self,
        mhi: &Mhi,
        target: &Camera,
        weights_of: impl FnOnce(&[f32]) -> crate::Result<Vec<f32>>,
    ) -> crate::Result<Blended> {
        let t0 = Instant::now();
        let soft =
            heuristic_weights_for(mhi.normals(), mhi.reference(), target, BlendHeuristic::Soft);
        let weights = weights_of(&soft)?;
        let image = combine(&self.images, &weights);
        Ok(Blended {
            image,
            weights,
            blend_ms: ms(t0),
        })
    }
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}
