//! A trained run loaded for inference: stage 1 turns two posed views into an MHI, the blending
//! network turns its multi-normal images into per-pixel weights.

use std::path::Path;

use burn::tensor::{Device, Tensor, TensorData};
use image::Rgb32FImage;
use mhi_data::LoadedFrame;
use mhi_geom::{NormalSet, depths_linear_in_disparity};
use mhi_render::diff::image_to_tensor;
use mhi_render::{LayerColor, Mhi, plane_sweep_volume};

use crate::Error;
use crate::nets::{BlendNet, Stage1};
use crate::train::{Latest, TrainConfig, load_networks};

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
        let cfg_path = run.join("config.json");
        let text = std::fs::read_to_string(&cfg_path).map_err(|e| Error::Io {
            path: cfg_path.clone(),
            source: e,
        })?;
        let config: TrainConfig = TrainConfig::from_json(&text, &cfg_path)?;
        let latest_path = run.join("latest.json");
        let latest: Latest =
            serde_json::from_str(&std::fs::read_to_string(&latest_path).map_err(|e| {
                Error::Io {
                    path: latest_path.clone(),
                    source: e,
                }
            })?)
            .map_err(|e| Error::Checkpoint(format!("{}: {e}", latest_path.display())))?;
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

    /// Check that a view size suits the U-Nets (each side divisible by `2^levels`).
    pub fn check_size(&self, width: u32, height: u32) -> crate::Result<()> {
        let m = 1u32 << self.config.stage1.unet.levels.max(self.config.blend.levels);
        if width == 0 || height == 0 || !width.is_multiple_of(m) || !height.is_multiple_of(m) {
            return Err(Error::Config(format!(
                "image size {width}x{height}: each side must be a positive multiple of {m} for this model"
            )));
        }
        Ok(())
    }

    /// The oriented cost volume of two views.
    ///
    /// # Shapes
    /// returns `[N, 6, D, H, W]`
    pub fn cost_volume(
        &self,
        reference: &LoadedFrame,
        source: &LoadedFrame,
    ) -> crate::Result<Tensor<5>> {
        cost_volume(&self.normals, &self.depths, reference, source, &self.device)
    }

    /// Stage 1: alphas `N · D · H · W` (normal-major, far first) from a cost volume.
    pub fn alphas(&self, volume: Tensor<5>) -> crate::Result<Vec<f32>> {
        let v: Vec<f32> = self
            .stage1
            .forward(volume)
            .into_data()
            .try_to_vec()
            .map_err(|e| Error::NonFinite(format!("stage-1 output: {e:?}")))?;
        if let Some(k) = v.iter().position(|a| !a.is_finite()) {
            return Err(Error::NonFinite(format!(
                "stage 1 produced {} at alpha {k}",
                v[k]
            )));
        }
        Ok(v.into_iter().map(|a| a.clamp(0.0, 1.0)).collect())
    }

    /// The MHI of the reference view with the given alphas.
    pub fn mhi(&self, reference: &LoadedFrame, alphas: Vec<f32>) -> crate::Result<Mhi> {
        Mhi::new(
            self.normals.clone(),
            self.depths.clone(),
            reference.camera,
            LayerColor::Shared(reference.image.clone()),
            alphas,
        )
        .map_err(Error::from)
    }

    /// Stage 2: per-pixel blending weights `N × H × W` (normal-major, summing to 1) from the N
    /// multi-normal images and their Soft weights (`N × H × W`) on the target grid.
    pub fn blend_weights(&self, mni: &[Rgb32FImage], soft: &[f32]) -> crate::Result<Vec<f32>> {
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
        let input = Tensor::cat(
            vec![
                Tensor::cat(images, 0).reshape([1, 3 * n, h, w]),
                Tensor::from_data(TensorData::new(soft.to_vec(), [1, n, h, w]), &self.device),
            ],
            1,
        );
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

/// The oriented cost volume `[N, 6, D, H, W]`: per normal and plane, the reference image and the
/// source image warped onto that plane (zero where the plane is not visible from the source).
pub fn cost_volume(
    normals: &NormalSet,
    depths: &[f64],
    reference: &LoadedFrame,
    source: &LoadedFrame,
    device: &Device,
) -> crate::Result<Tensor<5>> {
    let psv = plane_sweep_volume(
        normals,
        depths,
        &reference.camera,
        &source.image,
        &source.camera,
    )?;
    let (n, d) = (normals.len(), depths.len());
    let (w, h) = (
        reference.image.width() as usize,
        reference.image.height() as usize,
    );
    let px = w * h;
    let refp = reference.image.as_raw();
    let mut data = vec![0.0_f32; n * 6 * d * px];
    for i in 0..n {
        for c in 0..6 {
            for j in 0..d {
                let dst = &mut data[((i * 6 + c) * d + j) * px..((i * 6 + c) * d + j + 1) * px];
                if c < 3 {
                    for (p, v) in dst.iter_mut().enumerate() {
                        *v = refp[3 * p + c];
                    }
                } else {
                    let src = psv.plane_rgb(i, j);
                    for (p, v) in dst.iter_mut().enumerate() {
                        *v = src[3 * p + c - 3];
                    }
                }
            }
        }
    }
    Ok(Tensor::from_data(
        TensorData::new(data, [n, 6, d, h, w]),
        device,
    ))
}
