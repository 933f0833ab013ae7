//! The project's methods as [`Method`]s, for [`crate::protocol::evaluate`]: the training-free
//! plane-sweep MHI ([`Sweep`]), a trained model with its learned or a heuristic blend
//! ([`Trained`]), and the input view nearest the target ([`Nearest`]). Each renders the way
//! `cargo xtask eval` scores it.

use std::time::Instant;

use mhi_data::LoadedFrame;
use mhi_geom::{BlendHeuristic, Camera, NormalSet, depths_linear_in_disparity};
use mhi_net::{BlendChoice, MhiSource, Model, ViewSynthesis, multi_normal};
use mhi_render::{Blend, Prune, RenderOptions, SweepConfig, render};

use crate::protocol::{Method, MethodError, Output};
use crate::report::{Config, Times};

/// The training-free MHI: plane-sweep photo-consistency over the paper's `normals` and planes
/// linear in disparity, rendered with the Soft blend within `prune`'s budget.
#[derive(Debug, Clone)]
pub struct Sweep {
    /// The paper's normal set of this size (1, 2, 3 or 5).
    pub normals: usize,
    /// Plane depths, far first.
    pub depths: Vec<f64>,
    /// The sweep's constants at a short side of 256 (scaled to each image's).
    pub config: SweepConfig,
    /// What the render may leave out.
    pub prune: Prune,
}

impl Sweep {
    /// `normals` × `planes` between depths `near` and `far`, the default constants and render
    /// plan.
    ///
    /// # Errors
    /// A normal count without a paper set, or a depth range that is not `0 < near < far`.
    pub fn new(normals: usize, planes: usize, near: f64, far: f64) -> mhi_geom::Result<Self> {
        NormalSet::paper_subset(normals)?;
        Ok(Self {
            normals,
            depths: depths_linear_in_disparity(near, far, planes)?,
            config: SweepConfig::default(),
            prune: Prune::default(),
        })
    }
}

impl Method for Sweep {
    fn config(&self) -> Config {
        ("sweep".into(), self.normals, self.depths.len())
    }

    fn render(
        &mut self,
        reference: &LoadedFrame,
        source: &LoadedFrame,
        target: &Camera,
    ) -> Result<Output, MethodError> {
        let short = reference.image.width().min(reference.image.height());
        let (mhi, t) = ViewSynthesis::new(MhiSource::Sweep {
            normals: NormalSet::paper_subset(self.normals)?,
            depths: self.depths.clone(),
            config: self.config.scaled_to_short_side(short),
        })
        .mhi(reference, source)?;
        let t0 = Instant::now();
        let view = render(
            &mhi,
            target,
            &RenderOptions {
                blend: Blend::Heuristic(BlendHeuristic::Soft),
                prune: self.prune,
                keep_multi_normal: false,
            },
        )?;
        Ok(Output {
            image: view.image,
            times: Times {
                volume_ms: t.volume_ms,
                render_ms: t0.elapsed().as_secs_f64() * 1e3,
                ..Times::default()
            },
        })
    }
}

/// A trained run (`mhi_net::Model`): stage 1 builds the MHI, its N multi-normal images are
/// rendered within `prune`'s budget and blended by `blend` (an MPI, N = 1, has one image).
pub struct Trained {
    /// The model.
    pub model: Model,
    /// The blend: the learned network or one of the paper's heuristics.
    pub blend: BlendChoice,
    /// What the render may leave out.
    pub prune: Prune,
}

impl Method for Trained {
    fn config(&self) -> Config {
        let (n, d) = (self.model.normals().len(), self.model.depths().len());
        let name = match self.blend {
            _ if n == 1 => "mpi",
            BlendChoice::Learned => "learned",
            BlendChoice::Heuristic(BlendHeuristic::Soft) => "soft",
            BlendChoice::Heuristic(BlendHeuristic::Hard) => "hard",
            BlendChoice::Heuristic(BlendHeuristic::Avg) => "avg",
        };
        (name.into(), n, d)
    }

    fn render(
        &mut self,
        reference: &LoadedFrame,
        source: &LoadedFrame,
        target: &Camera,
    ) -> Result<Output, MethodError> {
        let (mhi, t) =
            ViewSynthesis::new(MhiSource::Learned(&self.model)).mhi(reference, source)?;
        let mn = multi_normal(&mhi, target, self.prune)?;
        let times = Times {
            volume_ms: t.volume_ms,
            network_ms: t.network_ms,
            render_ms: mn.render_ms,
            blend_ms: 0.0,
        };
        if mhi.n() == 1 {
            let image = mn
                .images
                .into_iter()
                .next()
                .ok_or("no multi-normal image")?;
            return Ok(Output { image, times });
        }
        let b = mn.blend(&mhi, Some(&self.model), target, self.blend)?;
        Ok(Output {
            image: b.image,
            times: Times {
                blend_ms: b.blend_ms,
                ..times
            },
        })
    }
}

/// The input view whose camera centre is nearest the target's, shown as it is.
#[derive(Debug, Clone, Copy, Default)]
pub struct Nearest;

impl Method for Nearest {
    fn config(&self) -> Config {
        ("nearest".into(), 0, 0)
    }

    fn render(
        &mut self,
        reference: &LoadedFrame,
        source: &LoadedFrame,
        target: &Camera,
    ) -> Result<Output, MethodError> {
        Ok(Output {
            image: nearest_input(reference, source, target).image.clone(),
            times: Times::default(),
        })
    }
}

/// Of the two inputs, the one whose camera centre is nearest `target`'s (the reference on a
/// tie).
pub fn nearest_input<'a>(
    reference: &'a LoadedFrame,
    source: &'a LoadedFrame,
    target: &Camera,
) -> &'a LoadedFrame {
    let c = target.center_in_world();
    let dr = (reference.camera.center_in_world() - c).length();
    let ds = (source.camera.center_in_world() - c).length();
    if dr <= ds { reference } else { source }
}
