//! A trained run loaded for inference: stage 1 turns two posed views into an MHI, the blending
//! network turns its multi-normal images into per-pixel weights.

use std::path::Path;

use burn::tensor::{Device, Tensor, TensorData};
use image::Rgb32FImage;
use mhi_data::LoadedFrame;
use mhi_geom::{NormalSet, depths_linear_in_disparity};
use mhi_render::diff::image_to_tensor;
use mhi_render::{LayerColor, Mhi};

use crate::Error;
use crate::config::TrainConfig;
use crate::nets::{BlendNet, Stage1};
use crate::run::RunDir;
use crate::train::{alphas_of, load_networks};
use crate::volume::{Stage1Input, stage1_input_with};

/// A trained model (the networks of a run's latest checkpoint) on a non-autodiff device.
pub struct Model {
    config: TrainConfig,
    normals: NormalSet,
    depths: Vec<f64>,
    stage1: Stage1,
    blend: BlendNet,
    device: Device,
    step: usize,
}

impl Model {
    /// Load the latest checkpoint of the run in `run`.
    pub fn load(run: &Path, device: Device) -> crate::Result<Self> {
        let dir = RunDir::new(run);
        let config = dir.config()?;
        let latest = dir.latest()?;
        let (stage1, blend) = load_networks(&config, &run.join(&latest.dir), &device)?;
        Self::with_networks(config, stage1, blend, device, latest.step)
    }

    fn with_networks(
        config: TrainConfig,
        stage1: Stage1,
        blend: BlendNet,
        device: Device,
        step: usize,
    ) -> crate::Result<Self> {
        let normals = config.normal_set()?;
        let depths = depths_linear_in_disparity(config.near, config.far, config.planes)?;
        Ok(Self {
            config,
            normals,
            depths,
            stage1,
            blend,
            device,
            step,
        })
    }

    /// The networks of `config` with their initial weights (the seed's): what a run starts
    /// from. Costs exactly what a trained model costs, so benchmarks of inference use it.
    pub fn untrained(config: TrainConfig, device: Device) -> crate::Result<Self> {
        let (stage1, blend) = crate::train::init_models(&config, &device);
        Self::with_networks(config, stage1, blend, device, 0)
    }

    /// The run's configuration.
    pub fn config(&self) -> &TrainConfig {
        &self.config
    }
    /// The normals.
    pub fn normals(&self) -> &NormalSet {
        &self.normals
    }
    /// The plane depths, far first.
    pub fn depths(&self) -> &[f64] {
        &self.depths
    }
    /// Training steps behind the loaded checkpoint.
    pub fn step(&self) -> usize {
        self.step
    }
    /// Whether the run trained its blending network (phase 2 started).
    pub fn blend_trained(&self) -> bool {
        self.step > self.config.phase1_steps
    }

    /// The pixel blocks stage 1 runs on for a `width × height` input: the training scale times
    /// the ratio of this short side to the training short side (rounded, when the image
    /// divides by it), so the U-Net sees the scene at the resolution it was trained at. Only
    /// with the sweep prior (only a correction is coarse then); without it, the training scale.
    pub fn stage1_scale(&self, width: usize, height: usize) -> usize {
        let base = self.config.stage1.scale.max(1);
        if self.config.prior != crate::volume::Prior::Sweep {
            return base;
        }
        let trained = self.config.width.min(self.config.height) as f64;
        let ratio = (width.min(height) as f64 / trained).round().max(1.0) as usize;
        let scale = base * ratio;
        let m = scale << self.config.stage1.unet.levels;
        if ratio > 1 && width.is_multiple_of(m) && height.is_multiple_of(m) {
            scale
        } else {
            base
        }
    }

    /// Check that a view size suits the U-Nets (each side divisible by `2^levels`).
    pub fn check_size(&self, width: u32, height: u32) -> crate::Result<()> {
        let m = self.config.size_multiple() as u32;
        if width == 0 || height == 0 || !width.is_multiple_of(m) || !height.is_multiple_of(m) {
            return Err(Error::Config(format!(
                "image size {width}x{height}: each side must be a positive multiple of {m} for this model"
            )));
        }
        Ok(())
    }

    /// Stage 1's input for two views: the oriented cost volume `[N, C, D, H, W]` and, for a
    /// model on the sweep prior, the sweep's logits on this image size.
    pub fn stage1_input(
        &self,
        reference: &LoadedFrame,
        source: &LoadedFrame,
    ) -> crate::Result<Stage1Input> {
        let (w, h) = (reference.image.width(), reference.image.height());
        stage1_input_with(
            &self.normals,
            &self.depths,
            reference,
            source,
            self.config
                .prior_sweep(w, h)
                .as_ref()
                .map(|c| (c, self.config.prior_eps())),
            self.stage1_scale(w as usize, h as usize),
            self.config.stage1.unet.colour_head,
            &self.device,
        )
    }

    /// Stage 1: alphas `N · D · H · W` (normal-major, far first) from its input.
    pub fn alphas(&self, input: Stage1Input) -> crate::Result<Vec<f32>> {
        Ok(self.layers(input)?.0)
    }

    /// Stage 1: alphas `N · D · H · W` (normal-major, far first) and the layers' colour: the
    /// reference's for every layer, or with a colour head each layer's own (one picture per
    /// layer, normal-major, far first).
    pub fn layers(
        &self,
        input: Stage1Input,
    ) -> crate::Result<(Vec<f32>, Option<Vec<Rgb32FImage>>)> {
        let data = |t: burn::tensor::TensorData| -> crate::Result<Vec<f32>> {
            t.try_to_vec()
                .map_err(|e| Error::NonFinite(format!("stage-1 output: {e:?}")))
        };
        let mut colours = None;
        let v: Vec<f32> = match &input.prior {
            // With the sweep prior, the networks' coarse residual is upsampled and applied to
            // the prior in one pass on the CPU (the same alphas as `alphas_of` to rounding),
            // and so is a colour head's mix.
            Some(prior) => {
                let [n, _, d, hs, ws] = input.volume.dims();
                let out = self.stage1.forward_full(input.volume);
                let c = out.dims()[1];
                if let (Some(sc), 2) = (&input.colour, c) {
                    let m = data(out.clone().narrow(1, 1, 1).into_data())?;
                    if let Some(k) = mhi_render::first_failing(&m, f32::is_finite) {
                        return Err(Error::NonFinite(format!(
                            "stage 1 produced {} at colour logit {k}",
                            m[k]
                        )));
                    }
                    colours = Some(sc.apply_upsampled(&m, (hs, ws)));
                }
                let small = data(out.narrow(1, 0, 1).reshape([n * d * hs * ws]).into_data())?;
                prior.apply_upsampled(&small, (hs, ws))
            }
            None => data(alphas_of(&self.stage1, input).alpha.into_data())?,
        };
        use rayon::prelude::*;
        if let Some(k) = mhi_render::first_failing(&v, f32::is_finite) {
            return Err(Error::NonFinite(format!(
                "stage 1 produced {} at alpha {k}",
                v[k]
            )));
        }
        let mut v = v;
        v.par_iter_mut().for_each(|a| *a = a.clamp(0.0, 1.0));
        Ok((v, colours))
    }

    /// The MHI of the reference view with the given alphas, every layer in the reference's
    /// colour.
    pub fn mhi(&self, reference: &LoadedFrame, alphas: Vec<f32>) -> crate::Result<Mhi> {
        self.mhi_with(reference, alphas, None)
    }

    /// The MHI of the reference view with the given alphas and layer colours (the reference's
    /// for every layer when `None`), as [`Self::layers`] gives them.
    pub fn mhi_with(
        &self,
        reference: &LoadedFrame,
        alphas: Vec<f32>,
        colours: Option<Vec<Rgb32FImage>>,
    ) -> crate::Result<Mhi> {
        let color = match colours {
            Some(v) => LayerColor::PerLayer(v),
            None => LayerColor::Shared(reference.image.clone()),
        };
        Mhi::new(
            self.normals.clone(),
            self.depths.clone(),
            reference.camera,
            color,
            alphas,
        )
        .map_err(Error::from)
    }

    /// The β of a blending network that reads each normal's photo-inconsistency, `None` for
    /// one that does not (see [`Self::blend_weights`]).
    pub fn blend_consistency(&self) -> Option<f32> {
        self.config.blend.consistency
    }

    /// Stage 2: per-pixel blending weights `N × H × W` (normal-major, summing to 1) from the N
    /// multi-normal images and their Soft weights (`N × H × W`) on the target grid, and for a
    /// network that reads them ([`Self::blend_consistency`]) the N inconsistency images of the
    /// same view (`crate::inconsistency`).
    pub fn blend_weights(
        &self,
        mni: &[Rgb32FImage],
        soft: &[f32],
        inconsistency: Option<&[Rgb32FImage]>,
    ) -> crate::Result<Vec<f32>> {
        let n = self.normals.len();
        let Some(first) = mni.first() else {
            return Err(Error::Config("no multi-normal image".into()));
        };
        let (w, h) = (first.width() as usize, first.height() as usize);
        if mni.len() != n || soft.len() != n * w * h {
            return Err(Error::Config(format!(
                "expected {n} multi-normal images and {} weights, got {} and {}",
                n * w * h,
                mni.len(),
                soft.len()
            )));
        }
        let images: Vec<Tensor<4>> = mni
            .iter()
            .map(|m| image_to_tensor(m, &self.device))
            .collect();
        let mut parts = vec![
            Tensor::cat(images, 0).reshape([1, 3 * n, h, w]),
            Tensor::from_data(TensorData::new(soft.to_vec(), [1, n, h, w]), &self.device),
        ];
        match (self.config.blend.consistency, inconsistency) {
            (None, _) => {}
            (Some(_), None) => {
                return Err(Error::Config(
                    "this model's blending network reads each normal's photo-inconsistency: blend it through mhi_net::Consistency".into(),
                ));
            }
            (Some(_), Some(inc)) => {
                if inc.len() != n || inc.iter().any(|m| m.dimensions() != first.dimensions()) {
                    return Err(Error::Config(format!(
                        "expected {n} inconsistency images of {w}x{h}"
                    )));
                }
                parts.push(Tensor::from_data(
                    TensorData::new(mhi_render::inconsistency_means(inc), [1, n, h, w]),
                    &self.device,
                ));
            }
        }
        let input = Tensor::cat(parts, 1);
        let v: Vec<f32> = self
            .blend
            .forward(input)
            .into_data()
            .try_to_vec()
            .map_err(|e| Error::NonFinite(format!("blending output: {e:?}")))?;
        if v.iter().any(|x| !x.is_finite()) {
            return Err(Error::NonFinite(
                "the blending network produced a non-finite weight".into(),
            ));
        }
        Ok(v)
    }
}
