//! A training run's configuration: everything that defines it, saved as `config.json` in the
//! run directory, with the migration of configs written by earlier versions.

use std::path::Path;

use burn::config::Config;
use burn::grad_clipping::GradientClippingConfig;
use burn::optim::AdamConfig;
use mhi_data::DataSource;
use mhi_geom::NormalSet;
use mhi_render::SweepConfig;

use crate::Error;
use crate::loss::LossKind;
use crate::nets::{BlendNetConfig, Stage1Config, UNet3dConfig};
use crate::volume::Prior;

/// Norm to which gradients are clipped by default.
pub const GRAD_CLIP_NORM: f32 = 1.0;

/// Everything that defines a training run; saved as `config.json` in the run directory.
#[derive(Config, Debug)]
pub struct TrainConfig {
    /// Stage-1 networks.
    pub stage1: Stage1Config,
    /// Blending network.
    pub blend: BlendNetConfig,
    /// Optimizer (Adam; the paper's learning rate is `lr`).
    pub optimizer: AdamConfig,
    /// Learning rate.
    #[config(default = 2e-4)]
    pub lr: f64,
    /// Seed of the initial weights and of every step's triplet.
    #[config(default = 0)]
    pub seed: u64,
    /// Training image width.
    #[config(default = 64)]
    pub width: u32,
    /// Training image height.
    #[config(default = 64)]
    pub height: u32,
    /// Planes per normal D.
    #[config(default = 8)]
    pub planes: usize,
    /// Nearest plane depth.
    #[config(default = 1.0)]
    pub near: f64,
    /// Farthest plane depth.
    #[config(default = 100.0)]
    pub far: f64,
    /// Steps of phase 1 (stage 1 on every multi-normal image).
    #[config(default = 280)]
    pub phase1_steps: usize,
    /// Steps of phase 2 (blending network, stage 1 frozen).
    #[config(default = 140)]
    pub phase2_steps: usize,
    /// Write a checkpoint every this many steps (and at the end).
    #[config(default = 50)]
    pub checkpoint_every: usize,
    /// Held-out samples scored at every checkpoint (`val.csv`; 0 turns it off).
    #[config(default = 4)]
    pub val_samples: usize,
    /// Factor of the VGG feature term of the perceptual loss (see
    /// `loss::DEFAULT_PERCEPTUAL_WEIGHT`).
    #[config(default = "crate::loss::DEFAULT_PERCEPTUAL_WEIGHT")]
    pub perceptual_weight: f32,
    /// The loss actually used, as a formula (filled in by the trainer).
    #[config(default = "String::new()")]
    pub loss: String,
    /// Which loss that is (filled in by the trainer): what resuming the run needs.
    #[config(default = "LossKind::Photometric")]
    pub loss_kind: LossKind,
    /// The training data: roots, splits, weights of the mix and the sequences held out for
    /// validation. Empty in runs written before it was recorded (they trained on one root).
    #[config(default = "Vec::new()")]
    pub data: Vec<DataSource>,
    /// What stage 1 starts from: nothing (the paper's network) or the training-free sweep,
    /// whose alpha logits it corrects (see [`TrainConfig::with_sweep_prior`]).
    #[config(default = "Prior::None")]
    pub prior: Prior,
    /// Score only the target pixels the reference covers (others are replaced by the target
    /// before the loss, so they add no error and no gradient).
    #[config(default = false)]
    pub covered_loss: bool,
    /// The chance that a training triplet is an extrapolation (target outside the two inputs)
    /// rather than an interpolation; Stereo Magnification draws them 50/50. Validation samples
    /// are always drawn 50/50, so runs with different shares validate on the same triplets.
    #[config(default = "mhi_data::PAPER_EXTRAPOLATION_SHARE")]
    pub extrapolation_share: f64,
    /// How training triplets are drawn: Stereo Magnification's clips (every run before this
    /// field existed) or nearest views by camera centre, where `extrapolation_share` is unused
    /// (the kind follows from the views). Validation always draws clips.
    #[config(default = "mhi_data::TripletSampling::Clips")]
    pub triplet_sampling: mhi_data::TripletSampling,
    /// How a training or validation frame is brought to `width × height`: stretched (Stereo
    /// Magnification's choice; every run before this field existed) or its largest centred
    /// region of that aspect cropped and resized, so that the network sees scenes at their
    /// own proportions. The camera follows either way.
    #[config(default = "mhi_data::Fit::Stretch")]
    pub fit: mhi_data::Fit,
    /// The stage-1 step from which stage 1 trains at `lr × lr_drop_factor` (`None`: `lr`
    /// throughout). The blending network's steps keep `lr`: it starts from zero. Runs written
    /// before this field existed read as `None`.
    #[config(default = "None")]
    pub lr_drop_at: Option<usize>,
    /// What the learning rate is multiplied by from `lr_drop_at` on.
    #[config(default = 0.1)]
    pub lr_drop_factor: f64,
    /// The sweep prior's window radius at a short side of
    /// [`SweepConfig::TUNED_SHORT_SIDE`] px, scaled with the image like the sweep's own
    /// (`None`: the sweep's default). Runs written before this field existed read as `None`.
    #[config(default = "None")]
    pub prior_window_radius: Option<u32>,
    /// The sweep prior's softmax temperature over depths (`None`: the sweep's default).
    #[config(default = "None")]
    pub prior_temperature: Option<f32>,
    /// The sweep prior's cost where the source does not see a pixel (`None`: the sweep's
    /// default).
    #[config(default = "None")]
    pub prior_invalid_cost: Option<f32>,
    /// Where the sweep prior's alphas are clamped before their logit is taken: `[c, 1 − c]`
    /// (`None`: [`crate::PRIOR_EPS`], every run before this field existed). The clamped-off
    /// remainder is added back as a constant, so an untrained model renders the sweep whatever
    /// `c`; but a residual on a clamped logit moves its alpha at rate `c (1 − c)`, so with
    /// `c = 1e-3` the alphas the sweep is sure of barely move under training.
    #[config(default = "None")]
    pub prior_clamp: Option<f32>,
    /// The run whose trained stage 1 this run started from (`Trainer::new_on_stage1`), as
    /// given; `None` for a run whose stage 1 started untrained.
    #[config(default = "None")]
    pub stage1_from: Option<String>,
    /// Stage 1 also learns from its multi-normal images blended consistently with this β
    /// (`render`'s default blend, weights held constant): half its loss is each normal's image
    /// alone (the paper's), half the blended image, so that each normal may specialise where the
    /// photos choose it. `None` (every run before this field existed): the per-normal loss
    /// alone. Needs the colour head's source colours.
    #[config(default = "None")]
    pub stage1_consistent_loss: Option<f32>,
}

impl TrainConfig {
    /// The default run for N normals: a CPU-sized model.
    pub fn for_normals(normals: usize) -> Self {
        TrainConfig::new(
            Stage1Config::new(UNet3dConfig::new(), normals),
            BlendNetConfig::new(normals),
            // Guard: gradients are clipped to norm 1, so a stiff step (high learning rate,
            // saturated alphas, a degenerate target) cannot throw the weights to infinity.
            AdamConfig::new()
                .with_grad_clipping(Some(GradientClippingConfig::Norm(GRAD_CLIP_NORM))),
        )
    }

    /// Parse a run's `config.json`; runs written before `val_samples` existed get 0 (they
    /// logged no validation), and runs written before `perceptual_weight` existed get the factor
    /// they trained with, `loss::VGG_FEATURE_SCALE`.
    pub fn from_json(text: &str, path: &Path) -> crate::Result<Self> {
        let bad = |e: serde_json::Error| Error::Config(format!("{}: {e}", path.display()));
        let mut v: serde_json::Value = serde_json::from_str(text).map_err(bad)?;
        if let Some(o) = v.as_object_mut() {
            o.entry("val_samples").or_insert(serde_json::json!(0));
            o.entry("perceptual_weight")
                .or_insert(serde_json::json!(crate::loss::VGG_FEATURE_SCALE));
            o.entry("prior").or_insert(serde_json::json!("None"));
            o.entry("covered_loss").or_insert(serde_json::json!(false));
            o.entry("extrapolation_share")
                .or_insert(serde_json::json!(mhi_data::PAPER_EXTRAPOLATION_SHARE));
            o.entry("triplet_sampling")
                .or_insert(serde_json::json!(mhi_data::TripletSampling::Clips));
            o.entry("fit")
                .or_insert(serde_json::json!(mhi_data::Fit::Stretch));
            o.entry("lr_drop_at").or_insert(serde_json::Value::Null);
            o.entry("lr_drop_factor").or_insert(serde_json::json!(0.1));
            for key in [
                "prior_window_radius",
                "prior_temperature",
                "prior_invalid_cost",
                "prior_clamp",
                "stage1_from",
                "stage1_consistent_loss",
            ] {
                o.entry(key).or_insert(serde_json::Value::Null);
            }
            // Runs written before `loss_kind` existed: the formula of the perceptual loss ended
            // with the legacy marker "(VGG16)".
            if !o.contains_key("loss_kind") {
                let perceptual = o
                    .get("loss")
                    .and_then(|l| l.as_str())
                    .is_some_and(|l| l.ends_with(crate::loss::PERCEPTUAL_SUFFIX));
                let kind = if perceptual {
                    LossKind::Perceptual
                } else {
                    LossKind::Photometric
                };
                o.insert("loss_kind".into(), serde_json::json!(kind));
            }
            if let Some(s1) = o.get_mut("stage1").and_then(|v| v.as_object_mut()) {
                s1.entry("scale").or_insert(serde_json::json!(1));
            }
            for part in [&["stage1", "unet"][..], &["blend"][..]] {
                let mut at = Some(&mut *o);
                for key in part {
                    at = at
                        .and_then(|m| m.get_mut(*key))
                        .and_then(|v| v.as_object_mut());
                }
                if let Some(m) = at {
                    m.entry("residual").or_insert(serde_json::json!(false));
                    if part.len() == 1 {
                        m.entry("disagreement").or_insert(serde_json::json!(false));
                    }
                    if part.len() == 2 {
                        m.entry("halve_planes").or_insert(serde_json::json!(false));
                        m.entry("norm_groups").or_insert(serde_json::json!(0));
                        m.entry("prototype_layout")
                            .or_insert(serde_json::json!(false));
                        m.entry("colour_head").or_insert(serde_json::json!(false));
                    }
                }
            }
        }
        serde_json::from_value(v).map_err(bad)
    }

    /// The same run on the sweep prior: stage 1 takes the sweep's logits as a seventh channel
    /// and predicts a zero-initialised residual on them, the blending network a zero-initialised
    /// residual on the log Soft weights, and the loss scores covered pixels only. Untrained, it
    /// renders the sweep blended with Soft.
    pub fn with_sweep_prior(mut self) -> Self {
        self.prior = Prior::Sweep;
        self.stage1.unet.in_channels = Prior::Sweep.channels();
        self.stage1.unet.residual = true;
        self.blend.residual = true;
        self.covered_loss = true;
        self
    }

    /// The sweep's constants for the prior on images of `width × height` (the window scaled
    /// with the short side), or `None` without the prior.
    pub fn prior_sweep(&self, width: u32, height: u32) -> Option<SweepConfig> {
        (self.prior == Prior::Sweep).then(|| {
            let d = SweepConfig::default();
            SweepConfig {
                window_radius: self.prior_window_radius.unwrap_or(d.window_radius),
                temperature: self.prior_temperature.unwrap_or(d.temperature),
                invalid_cost: self.prior_invalid_cost.unwrap_or(d.invalid_cost),
            }
            .scaled_to_short_side(width.min(height))
        })
    }

    /// Where the sweep prior's alphas are clamped before their logit is taken (see
    /// [`Self::prior_clamp`]).
    pub fn prior_eps(&self) -> f32 {
        self.prior_clamp.unwrap_or(crate::PRIOR_EPS)
    }

    /// Every image side must be a multiple of this: `2^levels` of each U-Net, times stage 1's
    /// scale.
    pub fn size_multiple(&self) -> usize {
        (self.stage1.scale.max(1) << self.stage1.unet.levels).max(1 << self.blend.levels)
    }

    /// The learning rate of global step `step`: `lr`, times `lr_drop_factor` for the stage-1
    /// steps from `lr_drop_at` on.
    pub fn lr_at(&self, step: usize) -> f64 {
        match self.lr_drop_at {
            Some(at) if step >= at && step < self.phase1_steps => self.lr * self.lr_drop_factor,
            _ => self.lr,
        }
    }

    /// Total number of steps of both phases.
    pub fn total_steps(&self) -> usize {
        self.phase1_steps + self.phase2_steps
    }

    /// The normal set (the paper's subsets).
    pub fn normal_set(&self) -> crate::Result<NormalSet> {
        let n = self.stage1.normals;
        Ok(NormalSet::paper_subset(n)?)
    }

    pub(crate) fn validate(&self) -> crate::Result<()> {
        self.check_sizes()?;
        self.normal_set()?;
        if let Some(beta) = self.blend.consistency {
            mhi_render::check_beta(beta)
                .map_err(|e| Error::Config(format!("blend.consistency: {e}")))?;
        }
        if let Some(beta) = self.stage1_consistent_loss {
            mhi_render::check_beta(beta)
                .map_err(|e| Error::Config(format!("stage1_consistent_loss: {e}")))?;
            if self.stage1.normals < 2 {
                return Err(Error::Config(
                    "stage1_consistent_loss weighs normals against each other: it needs 2 or more normals"
                        .into(),
                ));
            }
        }
        let m = self.size_multiple();
        if !(self.width as usize).is_multiple_of(m) || !(self.height as usize).is_multiple_of(m) {
            return Err(Error::Config(format!(
                "training size {}x{} must be divisible by {m} (the U-Nets halve the image {} times{})",
                self.width,
                self.height,
                self.stage1.unet.levels.max(self.blend.levels),
                if self.stage1.scale > 1 {
                    format!(", after stage 1 averages {0}x{0} blocks", self.stage1.scale)
                } else {
                    String::new()
                }
            )));
        }
        if self.planes == 0 || self.stage1.normals == 0 || self.blend.normals != self.stage1.normals
        {
            return Err(Error::Config(
                "planes and normals must be positive and agree between the stages".into(),
            ));
        }
        let unet = &self.stage1.unet;
        if unet.halve_planes && !self.planes.is_multiple_of(1 << unet.levels) {
            return Err(Error::Config(format!(
                "{} planes: a stage 1 that halves the plane axis {} times needs a plane count divisible by {}",
                self.planes,
                unet.levels,
                1 << unet.levels
            )));
        }
        if unet.colour_head && self.prior != Prior::Sweep {
            return Err(Error::Config(
                "stage1.unet.colour_head needs the sweep prior (a residual head that starts at zero)"
                    .into(),
            ));
        }
        if self.prior_window_radius == Some(0) {
            return Err(Error::Config(
                "prior_window_radius must be at least 1 pixel".into(),
            ));
        }
        if let Some(c) = self.prior_clamp {
            crate::volume::check_prior_clamp(c)?;
        }
        if let Some(t) = self.prior_temperature
            && !(t > 0.0 && t.is_finite())
        {
            return Err(Error::Config(format!(
                "prior_temperature {t}: must be a positive number"
            )));
        }
        if let Some(c) = self.prior_invalid_cost
            && !(0.0..=1.0).contains(&c)
        {
            return Err(Error::Config(format!(
                "prior_invalid_cost {c}: must lie in [0, 1] (a mean absolute colour difference)"
            )));
        }
        let (channels, residual) = (self.prior.channels(), self.prior == Prior::Sweep);
        if self.stage1.unet.in_channels != channels || self.stage1.unet.residual != residual {
            return Err(Error::Config(format!(
                "prior {:?} needs a stage-1 network with {channels} input channels and {} head; the config has {} channels and {} head",
                self.prior,
                if residual { "a residual" } else { "an alpha" },
                self.stage1.unet.in_channels,
                if self.stage1.unet.residual {
                    "a residual"
                } else {
                    "an alpha"
                },
            )));
        }
        if !(self.lr > 0.0 && self.lr.is_finite()) {
            return Err(Error::Config(format!(
                "learning rate {} must be positive",
                self.lr
            )));
        }
        if !(self.lr_drop_factor > 0.0 && self.lr_drop_factor <= 1.0) {
            return Err(Error::Config(format!(
                "lr_drop_factor {} must be in (0, 1]: it lowers the learning rate",
                self.lr_drop_factor
            )));
        }
        if let Some(at) = self.lr_drop_at
            && at >= self.phase1_steps
        {
            return Err(Error::Config(format!(
                "lr_drop_at {at} is not before the last of the {} stage-1 steps: the learning rate would never drop",
                self.phase1_steps
            )));
        }
        if !(0.0..=1.0).contains(&self.extrapolation_share) {
            return Err(Error::Config(format!(
                "extrapolation_share {} must be a chance between 0 and 1",
                self.extrapolation_share
            )));
        }
        if self.checkpoint_every == 0 {
            return Err(Error::Config("checkpoint_every must be at least 1".into()));
        }
        Ok(())
    }

    /// Every size that allocates, checked against what a model can sensibly have before
    /// anything is allocated: a config.json with absurd numbers is an error naming the field,
    /// not an allocation of gigabytes.
    fn check_sizes(&self) -> crate::Result<()> {
        let unet = &self.stage1.unet;
        let checks: [(&str, usize, usize, usize); 11] = [
            ("width", self.width as usize, 1, 4096),
            ("height", self.height as usize, 1, 4096),
            ("planes", self.planes, 1, 256),
            ("stage1.normals", self.stage1.normals, 1, 16),
            ("stage1.scale", self.stage1.scale, 1, 16),
            ("stage1.unet.width", unet.width, 1, 256),
            ("stage1.unet.levels", unet.levels, 0, 6),
            ("stage1.unet.in_channels", unet.in_channels, 1, 64),
            ("stage1.unet.dilations (count)", unet.dilations.len(), 0, 8),
            ("blend.width", self.blend.width, 1, 256),
            ("blend.levels", self.blend.levels, 0, 6),
        ];
        for (name, v, lo, hi) in checks {
            if !(lo..=hi).contains(&v) {
                return Err(Error::Config(format!(
                    "{name} = {v} is outside [{lo}, {hi}]: not a model this project can build (a damaged or foreign config.json?)"
                )));
            }
        }
        if let Some(d) = unet.dilations.iter().find(|d| !(1..=64).contains(*d)) {
            return Err(Error::Config(format!(
                "stage1.unet.dilations holds {d}: each must lie in [1, 64]"
            )));
        }
        Ok(())
    }

    /// What stage 1's weights mean: its network, the grid and the prior. Two runs that agree
    /// on it can share a trained stage 1 (`Trainer::new_on_stage1`).
    pub fn stage1_signature(&self) -> String {
        let mut v = vec![serde_json::json!(self.stage1)];
        v.extend(self.grid_and_prior());
        serde_json::Value::Array(v).to_string()
    }

    /// The grid and the prior, as the signature and the fingerprint list them.
    fn grid_and_prior(&self) -> [serde_json::Value; 8] {
        use serde_json::json;
        [
            json!(self.planes),
            json!(self.near),
            json!(self.far),
            json!(self.prior),
            json!(self.prior_window_radius),
            json!(self.prior_temperature),
            json!(self.prior_invalid_cost),
            json!(self.prior_clamp),
        ]
    }

    /// A fingerprint of everything that shapes the networks or what their weights mean (the
    /// networks' configs, the grid, the prior), stored with every checkpoint: weights of another
    /// model whose tensors happen to have the same shapes are refused instead of loaded.
    pub fn fingerprint(&self) -> String {
        // A blend option added after runs were trained is left out while off, so that their
        // checkpoints keep the fingerprint they were written with.
        let mut blend = serde_json::to_value(&self.blend).unwrap_or_default();
        if let Some(o) = blend.as_object_mut() {
            if o.get("disagreement") == Some(&serde_json::Value::Bool(false)) {
                o.remove("disagreement");
            }
            if o.get("consistency") == Some(&serde_json::Value::Null) {
                o.remove("consistency");
            }
        }
        let mut v = vec![serde_json::json!(self.stage1), blend];
        v.extend(self.grid_and_prior());
        let v = serde_json::Value::Array(v);
        // FNV-1a, 64 bits: stable across builds and platforms.
        let hash = v
            .to_string()
            .bytes()
            .fold(0xcbf2_9ce4_8422_2325_u64, |h, b| {
                (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
            });
        format!("{hash:016x}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A run's loss kind is recorded as an enum; runs written before it existed get theirs from
    /// the legacy formula, once, when their config.json is read.
    #[test]
    fn the_loss_kind_is_recorded_and_migrated_from_old_configs() {
        let mut c = TrainConfig::for_normals(2);
        c.loss_kind = LossKind::Perceptual;
        let text = serde_json::to_string(&c).unwrap();
        let back = TrainConfig::from_json(&text, Path::new("config.json")).unwrap();
        assert_eq!(back.loss_kind, LossKind::Perceptual);
        c.loss_kind = LossKind::L1;
        let l1 = serde_json::to_string(&c).unwrap();
        let back = TrainConfig::from_json(&l1, Path::new("config.json")).unwrap();
        assert_eq!(back.loss_kind, LossKind::L1);
        for (name, kind) in [
            ("L1 + 0.01*(conv1_2/2.6) (VGG16)", LossKind::Perceptual),
            (crate::loss::PHOTOMETRIC_NAME, LossKind::Photometric),
        ] {
            let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
            let o = v.as_object_mut().unwrap();
            o.remove("loss_kind");
            o.insert("loss".into(), serde_json::json!(name));
            let old = TrainConfig::from_json(&v.to_string(), Path::new("config.json")).unwrap();
            assert_eq!(old.loss_kind, kind, "{name}");
        }
    }

    /// Runs written before `fit` existed stretched their frames: they read as `Stretch`; a
    /// cropping run reads back as cropping.
    #[test]
    fn the_fit_is_recorded_and_migrated() {
        let mut c = TrainConfig::for_normals(2);
        c.fit = mhi_data::Fit::CenterCrop;
        let text = serde_json::to_string(&c).unwrap();
        let back = TrainConfig::from_json(&text, Path::new("config.json")).unwrap();
        assert_eq!(back.fit, mhi_data::Fit::CenterCrop);
        let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
        v.as_object_mut().unwrap().remove("fit");
        let old = TrainConfig::from_json(&v.to_string(), Path::new("config.json")).unwrap();
        assert_eq!(old.fit, mhi_data::Fit::Stretch);
    }

    /// The learning rate drops for stage-1 steps from `lr_drop_at` on and not for the blending
    /// network's; runs written before the drop existed read as never dropping; a drop that
    /// would never happen, or a factor that is not a drop, is refused.
    #[test]
    fn the_learning_rate_drops_where_the_config_says() {
        let mut c = TrainConfig::for_normals(2);
        c.lr = 1e-3;
        c.phase1_steps = 100;
        c.phase2_steps = 20;
        assert!((0..120).all(|s| c.lr_at(s) == 1e-3));
        c.lr_drop_at = Some(80);
        assert!(c.validate().is_ok());
        assert_eq!(c.lr_at(79), 1e-3);
        assert!((80..100).all(|s| (c.lr_at(s) - 1e-4).abs() < 1e-18));
        assert!((100..120).all(|s| c.lr_at(s) == 1e-3));
        let text = serde_json::to_string(&c).unwrap();
        let back = TrainConfig::from_json(&text, Path::new("config.json")).unwrap();
        assert_eq!((back.lr_drop_at, back.lr_drop_factor), (Some(80), 0.1));
        let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
        let o = v.as_object_mut().unwrap();
        o.remove("lr_drop_at");
        o.remove("lr_drop_factor");
        let old = TrainConfig::from_json(&v.to_string(), Path::new("config.json")).unwrap();
        assert_eq!(old.lr_drop_at, None);
        assert_eq!(old.lr_at(90), 1e-3);
        c.lr_drop_at = Some(100);
        let e = c.validate().unwrap_err().to_string();
        assert!(e.contains("lr_drop_at 100"), "{e}");
        c.lr_drop_at = Some(80);
        for bad in [0.0, 1.5, f64::NAN] {
            c.lr_drop_factor = bad;
            let e = c.validate().unwrap_err().to_string();
            assert!(e.contains("lr_drop_factor"), "{e}");
        }
    }

    /// Runs written before the extrapolation share existed drew half and half: they read as
    /// 0.5 (so they resume as they trained); a share that is not a chance is refused.
    #[test]
    fn the_extrapolation_share_is_migrated_and_checked() {
        let mut c = TrainConfig::for_normals(2);
        c.extrapolation_share = 0.75;
        let text = serde_json::to_string(&c).unwrap();
        let back = TrainConfig::from_json(&text, Path::new("config.json")).unwrap();
        assert_eq!(back.extrapolation_share, 0.75);
        let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
        v.as_object_mut().unwrap().remove("extrapolation_share");
        let old = TrainConfig::from_json(&v.to_string(), Path::new("config.json")).unwrap();
        assert_eq!(old.extrapolation_share, 0.5);
        assert!(c.validate().is_ok());
        for bad in [-0.1, 1.5, f64::NAN] {
            c.extrapolation_share = bad;
            let e = c.validate().unwrap_err().to_string();
            assert!(e.contains("extrapolation_share"), "{e}");
        }
    }

    /// Runs written before the triplet sampling existed drew clips: they read as `Clips` and
    /// resume as they trained; `Neighbours` survives the round trip.
    #[test]
    fn the_triplet_sampling_is_migrated() {
        let mut c = TrainConfig::for_normals(2);
        c.triplet_sampling = mhi_data::TripletSampling::Neighbours;
        let text = serde_json::to_string(&c).unwrap();
        let back = TrainConfig::from_json(&text, Path::new("config.json")).unwrap();
        assert_eq!(back.triplet_sampling, mhi_data::TripletSampling::Neighbours);
        let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
        v.as_object_mut().unwrap().remove("triplet_sampling");
        let old = TrainConfig::from_json(&v.to_string(), Path::new("config.json")).unwrap();
        assert_eq!(old.triplet_sampling, mhi_data::TripletSampling::Clips);
    }

    /// The sweep prior's constants: the sweep's defaults unless given, the radius scaled with
    /// the short side like the sweep's own; old runs read as the defaults; bad values are
    /// refused by name.
    #[test]
    fn the_prior_sweep_takes_its_constants_from_the_config() {
        let mut c = TrainConfig::for_normals(1).with_sweep_prior();
        assert_eq!(
            c.prior_sweep(192, 144),
            Some(SweepConfig::for_short_side(144))
        );
        c.prior_window_radius = Some(5);
        c.prior_temperature = Some(0.02);
        c.prior_invalid_cost = Some(0.5);
        assert_eq!(c.prior_eps(), crate::PRIOR_EPS);
        c.prior_clamp = Some(0.05);
        assert!(c.validate().is_ok());
        let p = c.prior_sweep(192, 144).unwrap();
        assert_eq!(p.window_radius, 3, "5 at 256 px is 3 at 144 px");
        assert_eq!((p.temperature, p.invalid_cost), (0.02, 0.5));
        let text = serde_json::to_string(&c).unwrap();
        let back = TrainConfig::from_json(&text, Path::new("config.json")).unwrap();
        assert_eq!(back.prior_sweep(192, 144), Some(p));
        assert_eq!(back.prior_eps(), 0.05);
        let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
        for key in [
            "prior_window_radius",
            "prior_temperature",
            "prior_invalid_cost",
            "prior_clamp",
        ] {
            v.as_object_mut().unwrap().remove(key);
        }
        let old = TrainConfig::from_json(&v.to_string(), Path::new("config.json")).unwrap();
        assert_eq!(
            old.prior_sweep(192, 144),
            Some(SweepConfig::for_short_side(144))
        );
        assert_eq!(
            old.prior_eps(),
            crate::PRIOR_EPS,
            "old runs keep their clamp"
        );
        for (field, bad) in [
            (
                "prior_window_radius",
                c.clone().with_prior_window_radius(Some(0)),
            ),
            (
                "prior_temperature",
                c.clone().with_prior_temperature(Some(f32::NAN)),
            ),
            (
                "prior_invalid_cost",
                c.clone().with_prior_invalid_cost(Some(1.5)),
            ),
            ("prior_clamp", c.clone().with_prior_clamp(Some(0.5))),
            ("prior_clamp", c.clone().with_prior_clamp(Some(0.0))),
        ] {
            let e = bad.validate().unwrap_err().to_string();
            assert!(e.contains(field), "{e}");
        }
    }

    /// Runs written before stage 1 could halve the plane axis, use group norms or take the
    /// prototype's layout read as none of them; a plane count the halving cannot divide is refused with the numbers.
    #[test]
    fn plane_halving_is_migrated_and_checked() {
        let mut c = TrainConfig::for_normals(1).with_sweep_prior();
        c.stage1.unet.halve_planes = true;
        c.planes = 32;
        assert!(c.validate().is_ok());
        let text = serde_json::to_string(&c).unwrap();
        let back = TrainConfig::from_json(&text, Path::new("config.json")).unwrap();
        assert!(back.stage1.unet.halve_planes);
        let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
        v["stage1"]["unet"]
            .as_object_mut()
            .unwrap()
            .remove("halve_planes");
        v["stage1"]["unet"]
            .as_object_mut()
            .unwrap()
            .remove("norm_groups");
        let unet = v["stage1"]["unet"].as_object_mut().unwrap();
        unet.insert("norm_groups".into(), serde_json::json!(4));
        let again = TrainConfig::from_json(&v.to_string(), Path::new("config.json")).unwrap();
        assert_eq!(again.stage1.unet.norm_groups, 4, "a present field is kept");
        let unet = v["stage1"]["unet"].as_object_mut().unwrap();
        unet.remove("norm_groups");
        unet.remove("prototype_layout");
        let old = TrainConfig::from_json(&v.to_string(), Path::new("config.json")).unwrap();
        assert!(!old.stage1.unet.halve_planes);
        assert_eq!(old.stage1.unet.norm_groups, 0);
        assert!(!old.stage1.unet.prototype_layout);
        c.planes = 30;
        let e = c.validate().unwrap_err().to_string();
        assert!(
            e.contains("30 planes") && e.contains("divisible by 4"),
            "{e}"
        );
    }
}
