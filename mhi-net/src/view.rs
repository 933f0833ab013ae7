//! View synthesis as one capability: make an MHI from a posed pair (a trained model or the
//! training-free sweep), then render any target view of it with a blend choice and an error
//! budget, getting the image, the multi-normal images, the weights and the time split.

use std::time::Instant;

use image::Rgb32FImage;
use mhi_data::LoadedFrame;
use mhi_geom::{BlendHeuristic, Camera, NormalSet};
use mhi_render::{
    Blend, Mhi, Prune, RenderOptions, RenderStats, SweepConfig, combine, heuristic_weights_for,
    render, sweep_mhi,
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
    /// Plane-sweep volume (and, for the sweep, its alphas).
    pub volume_ms: f64,
    /// Stage 1 (0 for the sweep).
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
            MhiSource::Sweep { .. } => None,
        }
    }

    /// The MHI of a posed pair, on the reference frame's grid.
    pub fn mhi(
        &self,
        reference: &LoadedFrame,
        source: &LoadedFrame,
    ) -> crate::Result<(Mhi, MhiTimes)> {
        let t0 = Instant::now();
        match &self.source {
            MhiSource::Learned(m) => {
                let input = m.stage1_input(reference, source)?;
                let volume_ms = ms(t0);
                let t1 = Instant::now();
                let alphas = m.alphas(input)?;
                let network_ms = ms(t1);
                Ok((
                    m.mhi(reference, alphas)?,
                    MhiTimes {
                        volume_ms,
                        network_ms,
                    },
                ))
            }
            MhiSource::Sweep {
                normals,
                depths,
                config,
            } => {
                let mhi = sweep_mhi(
                    normals,
                    depths,
                    &reference.camera,
                    &reference.image,
                    &source.camera,
                    &source.image,
                    config,
                )?;
                Ok((
                    mhi,
                    MhiTimes {
                        volume_ms: ms(t0),
                        network_ms: 0.0,
                    },
                ))
            }
        }
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
    let model = model.filter(|_| mhi.n() > 1);
    let t0 = Instant::now();
    match (blend, model) {
        (BlendChoice::Learned, Some(m)) => {
            let r = render(
                mhi,
                target,
                &RenderOptions {
                    blend: Blend::Heuristic(BlendHeuristic::Avg),
                    prune,
                    keep_multi_normal: true,
                },
            )?;
            let render_ms = ms(t0);
            let t1 = Instant::now();
            let soft =
                heuristic_weights_for(mhi.normals(), mhi.reference(), target, BlendHeuristic::Soft);
            let weights = m.blend_weights(&r.multi_normal, &soft)?;
            let image = combine(&r.multi_normal, &weights);
            Ok(View {
                image,
                multi_normal: r.multi_normal,
                weights,
                stats: r.stats,
                render_ms,
                blend_ms: ms(t1),
            })
        }
        (choice, _) => {
            let h = match choice {
                BlendChoice::Heuristic(h) => h,
                BlendChoice::Learned => BlendHeuristic::Soft,
            };
            let r = render(
                mhi,
                target,
                &RenderOptions {
                    blend: Blend::Heuristic(h),
                    prune,
                    keep_multi_normal: true,
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

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}
