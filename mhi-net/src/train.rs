//! The two-phase training loop: phase 1 trains stage 1 on every multi-normal image, phase 2
//! freezes it and trains the blending network on the blended image. Each step's triplet is a
//! pure function of `(seed, step)`, so a resumed run continues exactly as an uninterrupted one.

use std::path::{Path, PathBuf};
use std::time::Instant;

use burn::module::Module;
use burn::optim::{GradientsParams, ModuleOptimizer};
use burn::tensor::{Device, Tensor};
use mhi_data::{
    DataMix, DataSource, LoadedFrame, PAPER_EXTRAPOLATION_SHARE, TripletSampling, load_frame,
};
use mhi_geom::{BlendHeuristic, NormalSet, depths_linear_in_disparity};
use mhi_render::diff::{WarpGeometry, heuristic_weights_tensor, image_to_tensor, render_shared};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::Error;
use crate::config::TrainConfig;
use crate::loss::{LossKind, TrainLoss};
use crate::nets::{BlendNet, Stage1};
use crate::run::{Latest, RunDir};
use crate::volume::{Stage1Input, stage1_input_with};

/// Wall-clock split of one training step, in milliseconds.
#[derive(Debug, Clone, Copy, Default, Serialize, Deserialize)]
pub struct StepTimes {
    /// Loading frames and building the oriented cost volume (CPU).
    pub volume_ms: f64,
    /// Stage-1 forward.
    pub stage1_ms: f64,
    /// Warp, composite and (phase 2) the blending network forward.
    pub render_ms: f64,
    /// Loss.
    pub loss_ms: f64,
    /// Backward pass and optimizer step.
    pub backward_ms: f64,
}

/// What one step did.
#[derive(Debug, Clone, Copy, Serialize, Deserialize)]
pub struct StepReport {
    /// Step index (0-based) that was just taken.
    pub step: usize,
    /// 1 or 2.
    pub phase: u8,
    /// Loss value.
    pub loss: f32,
    /// PSNR of the trained output (mean over normals in phase 1) against the target.
    pub psnr: f32,
    /// Time split.
    pub times: StepTimes,
}

/// One training sample: the three views at the training size.
pub struct Sample {
    /// Reference view (the MHI's grid).
    pub reference: LoadedFrame,
    /// Source view.
    pub source: LoadedFrame,
    /// Target view.
    pub target: LoadedFrame,
}

/// A training run in progress.
pub struct Trainer {
    config: TrainConfig,
    dir: PathBuf,
    device: Device,
    train_data: DataMix,
    /// Validation data (a `val` split or held-out sequences); `None` when the sources have none,
    /// and validation then draws unseen triplets of the training sequences.
    val_data: Option<DataMix>,
    normals: NormalSet,
    depths: Vec<f64>,
    stage1: Stage1,
    blend: BlendNet,
    opt1: ModuleOptimizer,
    opt2: ModuleOptimizer,
    loss: TrainLoss,
    step: usize,
    started: Instant,
    elapsed_before: f64,
    /// The run folder's writer lock (see [`mhi_data::output`]): one trainer per run.
    _lock: Option<mhi_data::output::DirLock>,
}

fn io(path: &Path, e: std::io::Error) -> Error {
    Error::Io {
        path: path.to_path_buf(),
        source: e,
    }
}

/// The kind of output a run folder is (its [`mhi_data::output::OWNER_MARKER`]).
pub const RUN_KIND: &str = "training run";

fn data_error(e: mhi_data::Error) -> Error {
    Error::Data(Box::new(e))
}

fn write_atomic(path: &Path, bytes: &[u8]) -> crate::Result<()> {
    mhi_data::write_atomic(path, bytes).map_err(|e| Error::Data(Box::new(e)))
}

impl Trainer {
    /// Start a new run in `dir` (which must not hold a run yet) on `config.data` (when empty:
    /// the `train` split of `data_root`), minimising `loss` (its name is recorded in
    /// `config.json`).
    pub fn new(
        config: TrainConfig,
        dir: &Path,
        data_root: &Path,
        loss: TrainLoss,
        device: Device,
    ) -> crate::Result<Self> {
        Self::start(config, dir, data_root, loss, device, None)
    }

    /// As [`Self::new`], with stage 1 taken from the latest checkpoint of the trained run
    /// `from` (recorded as `config.stage1_from`), e.g. to train only a new blending network
    /// on it (`phase1_steps` 0). The two runs must agree on stage 1's network, grid and prior
    /// ([`TrainConfig::stage1_signature`]).
    ///
    /// # Errors
    /// As [`Self::new`]; if `from` holds no run with a checkpoint, or its stage 1 differs.
    pub fn new_on_stage1(
        mut config: TrainConfig,
        dir: &Path,
        data_root: &Path,
        loss: TrainLoss,
        device: Device,
        from: &Path,
    ) -> crate::Result<Self> {
        let run = RunDir::new(from);
        let theirs = run.config()?;
        if theirs.stage1_signature() != config.stage1_signature() {
            return Err(Error::Config(format!(
                "{}: its stage 1 (network, planes, depth range, prior) differs from this run's, so its weights cannot start this run",
                from.display()
            )));
        }
        let latest = run.latest()?;
        let (stage1, _) = load_networks(&theirs, &from.join(&latest.dir), &device)?;
        config.stage1_from = Some(format!("{} (step {})", from.display(), latest.step));
        Self::start(config, dir, data_root, loss, device, Some(stage1))
    }

    fn start(
        mut config: TrainConfig,
        dir: &Path,
        data_root: &Path,
        loss: TrainLoss,
        device: Device,
        stage1: Option<Stage1>,
    ) -> crate::Result<Self> {
        config.validate()?;
        if RunDir::new(dir).config_path().exists() {
            return Err(Error::Config(format!(
                "{} already holds a training run: resume it or start in another directory",
                dir.display()
            )));
        }
        if let TrainLoss::Perceptual { weight, .. } = &loss {
            config.perceptual_weight = *weight;
        }
        config.loss = loss.name();
        config.loss_kind = loss.kind();
        // The data is opened (and the data sources filled in) before anything is written, so a
        // start that fails leaves no half-made run behind.
        let (fresh, blend) = init_models(&config, &device);
        let stage1 = stage1.unwrap_or(fresh);
        let mut t = Self::assemble(config, dir, data_root, device, stage1, blend, loss, 0, 0.0)?;
        // The folder must be new, empty, or a run folder whose start was interrupted: never
        // one holding the user's files.
        let (_, lock, _) = mhi_data::output::claim_dir(dir, RUN_KIND).map_err(data_error)?;
        t._lock = Some(lock);
        write_atomic(
            &RunDir::new(dir).config_path(),
            serde_json::to_string_pretty(&t.config)
                .map_err(|e| Error::Config(e.to_string()))?
                .as_bytes(),
        )?;
        write_atomic(&RunDir::new(dir).log_path(), CSV_HEADER.as_bytes())?;
        write_atomic(&RunDir::new(dir).val_path(), VAL_CSV_HEADER.as_bytes())?;
        mhi_data::output::mark_dir(dir, RUN_KIND, true).map_err(data_error)?;
        // The training curve starts at the untrained model.
        t.log_validation()?;
        Ok(t)
    }

    /// Continue the run in `dir` from its latest checkpoint, with the loss its `config.json`
    /// names (the perceptual loss needs `weights/vgg16.safetensors`).
    pub fn resume(
        dir: &Path,
        data_root: &Path,
        weights: Option<&Path>,
        device: Device,
    ) -> crate::Result<Self> {
        let run = RunDir::new(dir);
        let cfg_path = run.config_path();
        // A run made before folders were marked: recognisably a run (its config and checkpoint
        // pointer parse), so it is adopted.
        if mhi_data::output::read_marker(dir).is_none()
            && run.config().is_ok()
            && run.latest().is_ok()
        {
            mhi_data::output::mark_dir(dir, RUN_KIND, true).map_err(data_error)?;
        }
        let (_, lock, _) = mhi_data::output::claim_dir(dir, RUN_KIND).map_err(data_error)?;
        let config = run.config()?;
        config.validate()?;
        // Every kind named: a new one cannot fall through to another loss on resume.
        let loss = match config.loss_kind {
            LossKind::Photometric => TrainLoss::Photometric,
            LossKind::L1 => TrainLoss::L1,
            LossKind::Perceptual => {
                match TrainLoss::from_weights(weights, config.perceptual_weight, &device) {
                    (l @ TrainLoss::Perceptual { .. }, _) => l,
                    (_, why) => {
                        return Err(Error::Config(format!(
                            "{}: the run trains with the VGG16 perceptual loss, but its weights cannot be loaded ({}); fetch the pretrained weights first",
                            cfg_path.display(),
                            why.unwrap_or_default()
                        )));
                    }
                }
            }
        };
        if !run.has_checkpoint() {
            return Err(Error::Config(format!(
                "{}: the run has no checkpoint yet to resume from; start it afresh",
                dir.display()
            )));
        }
        let latest = run.latest()?;
        let ck = dir.join(&latest.dir);
        let load = |what: &str| ck.join(format!("{what}.bpk"));
        let (stage1, blend) = load_networks(&config, &ck, &device)?;
        let state_path = ck.join("state.json");
        let state: CheckpointState = serde_json::from_str(
            &std::fs::read_to_string(&state_path).map_err(|e| io(&state_path, e))?,
        )
        .map_err(|e| Error::Checkpoint(format!("{}: {e}", state_path.display())))?;
        let mut t = Self::assemble(
            config,
            dir,
            data_root,
            device,
            stage1,
            blend,
            loss,
            latest.step,
            state.elapsed_s,
        )?;
        t.opt1 = t
            .opt1
            .clone()
            .load(load("opt1"))
            .map_err(|e| Error::Checkpoint(format!("{}: {e}", load("opt1").display())))?;
        t.opt2 = t
            .opt2
            .clone()
            .load(load("opt2"))
            .map_err(|e| Error::Checkpoint(format!("{}: {e}", load("opt2").display())))?;
        // Drop log rows written after the checkpoint by the interrupted run (a validation row
        // of step s is written just after the checkpoint of step s).
        for (name, header, bound) in [
            ("log.csv", CSV_HEADER, latest.step),
            ("val.csv", VAL_CSV_HEADER, latest.step + 1),
        ] {
            let log = dir.join(name);
            let text = std::fs::read_to_string(&log).unwrap_or_else(|_| header.into());
            let kept: String = text
                .lines()
                .enumerate()
                .filter(|(i, l)| {
                    *i == 0
                        || l.split(',')
                            .next()
                            .and_then(|s| s.parse::<usize>().ok())
                            .is_some_and(|s| s < bound)
                })
                .map(|(_, l)| format!("{l}\n"))
                .collect();
            write_atomic(&log, kept.as_bytes())?;
        }
        t._lock = Some(lock);
        Ok(t)
    }

    #[allow(clippy::too_many_arguments)]
    fn assemble(
        config: TrainConfig,
        dir: &Path,
        data_root: &Path,
        device: Device,
        stage1: Stage1,
        blend: BlendNet,
        loss: TrainLoss,
        step: usize,
        elapsed_before: f64,
    ) -> crate::Result<Self> {
        let mut config = config;
        if config.data.is_empty() {
            config.data = vec![DataSource::train(data_root)];
        }
        let data_err = |e| Error::Data(Box::new(e));
        let train_data = DataMix::training(&config.data).map_err(data_err)?;
        let val_data = DataMix::validation(&config.data).map_err(data_err)?;
        let normals = config.normal_set()?;
        let depths = depths_linear_in_disparity(config.near, config.far, config.planes)?;
        let opt1 = config.optimizer.init();
        let opt2 = config.optimizer.init();
        Ok(Self {
            config,
            dir: dir.to_path_buf(),
            device,
            train_data,
            val_data,
            normals,
            depths,
            stage1,
            blend,
            opt1,
            opt2,
            loss,
            step,
            started: Instant::now(),
            elapsed_before,
            _lock: None,
        })
    }

    /// The run's configuration.
    pub fn config(&self) -> &TrainConfig {
        &self.config
    }
    /// Steps taken so far.
    pub fn step_index(&self) -> usize {
        self.step
    }
    /// Whether both phases are done.
    pub fn finished(&self) -> bool {
        self.step >= self.config.total_steps()
    }
    /// Wall-clock seconds of training so far, across resumes.
    pub fn elapsed_s(&self) -> f64 {
        self.elapsed_before + self.started.elapsed().as_secs_f64()
    }
    /// The stage-1 networks.
    pub fn stage1(&self) -> &Stage1 {
        &self.stage1
    }
    /// Replace the stage-1 networks (e.g. with saturated alphas for a stress test).
    pub fn set_stage1(&mut self, stage1: Stage1) {
        self.stage1 = stage1;
    }
    /// The blending network.
    pub fn blend_net(&self) -> &BlendNet {
        &self.blend
    }

    /// The training sample of `step` (deterministic).
    pub fn sample(&self, step: usize) -> crate::Result<Sample> {
        self.sample_from(
            &self.train_data,
            step,
            self.config.triplet_sampling,
            self.config.extrapolation_share,
        )
    }

    /// Where validation samples come from, for the run's records.
    pub fn validation_source(&self) -> String {
        match &self.val_data {
            Some(v) => v
                .parts()
                .map(|(name, d, _)| {
                    let seqs: Vec<&str> = d.sequences.iter().map(|s| s.name.as_str()).collect();
                    if d.dir.ends_with("val") {
                        format!("{name}: val split ({} sequences)", seqs.len())
                    } else {
                        format!("{name}: held-out sequences {}", seqs.join(", "))
                    }
                })
                .collect::<Vec<_>>()
                .join("; "),
            None => "unseen triplets of the training sequences (the data has no val split and no held-out sequence)".into(),
        }
    }

    /// The `k`-th validation sample (deterministic): from the validation data when there is
    /// some, else drawn after training's range of steps from the training data.
    pub fn validation_sample(&self, k: usize) -> crate::Result<Sample> {
        match &self.val_data {
            // Always Stereo Magnification's clips, half and half: runs that train on other
            // triplets validate on the same ones.
            Some(v) => self.sample_from(v, k, TripletSampling::Clips, PAPER_EXTRAPOLATION_SHARE),
            None => self.sample_from(
                &self.train_data,
                1_000_000 + k,
                TripletSampling::Clips,
                PAPER_EXTRAPOLATION_SHARE,
            ),
        }
    }

    fn sample_from(
        &self,
        mix: &DataMix,
        step: usize,
        sampling: TripletSampling,
        extrapolation_share: f64,
    ) -> crate::Result<Sample> {
        let mut rng = ChaCha8Rng::seed_from_u64(
            self.config.seed ^ (step as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15),
        );
        let Some((seq, t)) = mix.sample(sampling, extrapolation_share, &mut rng) else {
            return Err(Error::Config(
                "no sequence yields a triplet (each needs 3 frames)".into(),
            ));
        };
        mhi_data::check_same_size(&[
            &seq.frames[t.reference],
            &seq.frames[t.source],
            &seq.frames[t.target],
        ])
        .map_err(|e| Error::Data(Box::new(e)))?;
        let size = Some((self.config.width, self.config.height));
        let load = |i: usize| {
            load_frame(&seq.frames[i], size, self.config.fit).map_err(|e| Error::Data(Box::new(e)))
        };
        Ok(Sample {
            reference: load(t.reference)?,
            source: load(t.source)?,
            target: load(t.target)?,
        })
    }

    /// Take one training step (phase 1 or 2 by the step index) and log it.
    pub fn step(&mut self) -> crate::Result<StepReport> {
        let t0 = Instant::now();
        let sample = self.sample(self.step)?;
        self.step_with(sample, t0)
    }

    /// Take one training step on a given sample (`t0` is when its loading began, for the time
    /// split).
    pub fn step_with(&mut self, sample: Sample, t0: Instant) -> crate::Result<StepReport> {
        let step = self.step;
        let phase = if step < self.config.phase1_steps {
            1
        } else {
            2
        };
        // Phase 2 runs the frozen stage 1 on the plain device: a graph recorded and never
        // backpropagated stays in memory (100 MB per step here).
        let device = if phase == 1 {
            self.device.clone()
        } else {
            self.plain()
        };
        let input = self.stage1_input_on(&sample, &device)?;
        let mut times = StepTimes {
            volume_ms: ms(t0),
            ..StepTimes::default()
        };
        let t1 = Instant::now();
        // A blending network that reads each normal's photo-inconsistency gets its layer
        // colours from the stage-1 input (the source warped onto every plane) before stage 1
        // takes it.
        let inc_colour = if phase == 2 {
            self.inconsistency_colour(&input, &device)
        } else {
            // Stage 1 learning from its consistently blended images reads the same colours,
            // as constants.
            self.config
                .stage1_consistent_loss
                .and(input.colour.as_ref())
                .map(|c| c.inconsistency(&self.plain()))
        };
        let layers = if phase == 1 {
            alphas_of(&self.stage1, input)
        } else {
            self.frozen_alphas_of(input).autodiff()
        };
        let n = self.normals.len();
        times.stage1_ms = ms(t1);
        let t2 = Instant::now();
        let inputs = self.render_inputs(&sample, &self.device)?;
        let RenderInputs {
            geom,
            color,
            soft,
            target,
            ..
        } = &inputs;
        let inc =
            inc_colour.map(|c| inconsistency_of(layers.alpha.clone(), c.autodiff(), geom, soft));
        let color = layers.colour_or(color);
        let (_, mni) = render_shared(layers.alpha, color, geom, soft.clone());
        let (output, blended) = if phase == 1 {
            let blended = self
                .config
                .stage1_consistent_loss
                .zip(inc)
                .map(|(beta, inc)| consistent_blend(mni.clone(), soft.clone(), inc, beta));
            (mni, blended)
        } else {
            let output = learned_blend(&self.blend, mni.detach(), soft.clone(), inc);
            (output, None)
        };
        times.render_ms = ms(t2);
        let t3 = Instant::now();
        let mut loss = self
            .loss
            .compute(inputs.scored(output.clone()), target.clone())?;
        if let Some(blended) = blended {
            let b = self.loss.compute(inputs.scored(blended), target.clone())?;
            loss = (loss + b).mul_scalar(0.5);
        }
        times.loss_ms = ms(t3);
        let target = target.clone();
        let t4 = Instant::now();
        let loss_value = scalar(loss.clone())?;
        if !loss_value.is_finite() {
            return Err(Error::NonFinite(format!(
                "loss at step {step} is {loss_value}"
            )));
        }
        let grads = loss.backward();
        if phase == 1 {
            let g = GradientsParams::from_grads(grads, &self.stage1);
            self.stage1 = self
                .opt1
                .step(self.config.lr_at(step), self.stage1.clone(), g);
        } else {
            let g = GradientsParams::from_grads(grads, &self.blend);
            self.blend = self.opt2.step(self.config.lr, self.blend.clone(), g);
        }
        times.backward_ms = ms(t4);
        let psnr = psnr_of(output.detach(), target, phase == 1, n)?;
        self.step += 1;
        let report = StepReport {
            step,
            phase,
            loss: loss_value,
            psnr,
            times,
        };
        self.append_log(&report)?;
        if self.step.is_multiple_of(self.config.checkpoint_every) || self.finished() {
            self.checkpoint()?;
        }
        Ok(report)
    }

    /// The training device without autodiff: frozen networks and evaluation run there, so they
    /// record no graph.
    fn plain(&self) -> Device {
        self.device.clone().without_autodiff()
    }

    /// The layer colours of each normal's photo-inconsistency (`[N·D, 3, H, W]`, see
    /// [`crate::SourceColour::inconsistency`]) when the blending network reads them.
    fn inconsistency_colour(&self, input: &Stage1Input, device: &Device) -> Option<Tensor<4>> {
        self.config.blend.consistency?;
        input.colour.as_ref().map(|c| c.inconsistency(device))
    }

    /// Stage 1's layers from a cost volume on the plain device, recording no graph.
    ///
    /// # Shapes
    /// `[N, C, D, H, W]` → `[N·D, 1, H, W]` (and `[N·D, 3, H, W]` with a colour head)
    fn frozen_alphas_of(&self, input: Stage1Input) -> Layers {
        alphas_of(&self.stage1.valid(), input)
    }

    /// The constant tensors of rendering a sample on `device`: warp grids, reference colour,
    /// Soft weights and the target image.
    fn render_inputs(&self, s: &Sample, device: &Device) -> crate::Result<RenderInputs> {
        let (r, t) = (&s.reference.camera, &s.target.camera);
        let covered = self.config.covered_loss.then(|| {
            let far = self.depths.first().copied().unwrap_or(self.config.far);
            let m: Vec<f32> = mhi_render::coverage::covered_mask(r, t, far)
                .into_iter()
                .map(f32::from)
                .collect();
            Tensor::from_data(
                burn::tensor::TensorData::new(m, [1, 1, t.height as usize, t.width as usize]),
                device,
            )
        });
        Ok(RenderInputs {
            geom: WarpGeometry::new(&self.normals, &self.depths, r, t, device)?,
            color: image_to_tensor(&s.reference.image, device),
            soft: heuristic_weights_tensor(&self.normals, r, t, BlendHeuristic::Soft, device),
            target: image_to_tensor(&s.target.image, device),
            covered,
        })
    }

    /// Stage 1's input for a sample: the oriented cost volume `[N, C, D, H, W]` (per normal
    /// and plane, the reference image and the source image warped onto that plane) and the
    /// sweep prior when the run has one.
    pub fn stage1_input(&self, s: &Sample) -> crate::Result<Stage1Input> {
        self.stage1_input_on(s, &self.device)
    }

    fn stage1_input_on(&self, s: &Sample, device: &Device) -> crate::Result<Stage1Input> {
        let (w, h) = (s.reference.image.width(), s.reference.image.height());
        stage1_input_with(
            &self.normals,
            &self.depths,
            &s.reference,
            &s.source,
            self.config
                .prior_sweep(w, h)
                .as_ref()
                .map(|c| (c, self.config.prior_eps())),
            self.config.stage1.scale,
            // The plane-sweep volume's colours are kept for a colour head and for a blending
            // network that reads each normal's photo-inconsistency.
            self.config.stage1.unet.colour_head
                || self.config.blend.consistency.is_some()
                || self.config.stage1_consistent_loss.is_some(),
            device,
        )
    }

    fn append_log(&self, r: &StepReport) -> crate::Result<()> {
        use std::io::Write as _;
        let path = RunDir::new(&self.dir).log_path();
        let mut f = std::fs::OpenOptions::new()
            .append(true)
            .create(true)
            .open(&path)
            .map_err(|e| io(&path, e))?;
        let t = r.times;
        writeln!(
            f,
            "{},{},{:.6},{:.4},{:.3},{:.2},{:.2},{:.2},{:.2},{:.2}",
            r.step,
            r.phase,
            r.loss,
            r.psnr,
            self.elapsed_s(),
            t.volume_ms,
            t.stage1_ms,
            t.render_ms,
            t.loss_ms,
            t.backward_ms
        )
        .map_err(|e| io(&path, e))
    }

    /// Write a checkpoint of the current state (models, optimizers, step), atomically: a new
    /// directory is filled, then `latest.json` is replaced to point at it, then older
    /// checkpoints are removed.
    pub fn checkpoint(&mut self) -> crate::Result<()> {
        let name = format!("ckpt-{:07}", self.step);
        let tmp = self.dir.join(format!(".tmp-{name}"));
        let _ = std::fs::remove_dir_all(&tmp);
        std::fs::create_dir_all(&tmp).map_err(|e| io(&tmp, e))?;
        let ck = |e: burn::store::RecordError| Error::Checkpoint(e.to_string());
        self.stage1
            .clone()
            .save_file(tmp.join("stage1.bpk"))
            .map_err(ck)?;
        self.blend
            .clone()
            .save_file(tmp.join("blend.bpk"))
            .map_err(ck)?;
        self.opt1.save(tmp.join("opt1.bpk")).map_err(ck)?;
        self.opt2.save(tmp.join("opt2.bpk")).map_err(ck)?;
        let state = CheckpointState {
            step: self.step,
            elapsed_s: self.elapsed_s(),
            config_fingerprint: Some(self.config.fingerprint()),
        };
        write_atomic(
            &tmp.join("state.json"),
            serde_json::to_string(&state)
                .map_err(|e| Error::Config(e.to_string()))?
                .as_bytes(),
        )?;
        let final_dir = self.dir.join(&name);
        let _ = std::fs::remove_dir_all(&final_dir);
        std::fs::rename(&tmp, &final_dir).map_err(|e| io(&final_dir, e))?;
        let latest = Latest {
            step: self.step,
            dir: name.clone(),
        };
        write_atomic(
            &RunDir::new(&self.dir).latest_path(),
            serde_json::to_string(&latest)
                .map_err(|e| Error::Config(e.to_string()))?
                .as_bytes(),
        )?;
        // Remove older checkpoints.
        if let Ok(rd) = std::fs::read_dir(&self.dir) {
            for e in rd.flatten() {
                let fname = e.file_name().to_string_lossy().into_owned();
                let ours = fname.len() == 12
                    && fname.starts_with("ckpt-")
                    && fname[5..].bytes().all(|b| b.is_ascii_digit());
                if ours && fname != name {
                    let _ = std::fs::remove_dir_all(e.path());
                }
            }
        }
        self.log_validation()
    }

    /// Score the held-out samples and append a row to `val.csv` (nothing if `val_samples` is 0).
    fn log_validation(&self) -> crate::Result<()> {
        if self.config.val_samples > 0 {
            let (learned, soft) = self.evaluate(self.config.val_samples)?;
            use std::io::Write as _;
            let path = RunDir::new(&self.dir).val_path();
            let mut f = std::fs::OpenOptions::new()
                .append(true)
                .create(true)
                .open(&path)
                .map_err(|e| io(&path, e))?;
            writeln!(
                f,
                "{},{:.3},{learned:.4},{soft:.4}",
                self.step,
                self.elapsed_s()
            )
            .map_err(|e| io(&path, e))?;
        }
        Ok(())
    }

    /// The phase-1 loss (mean over normals) on the training sample of `step`, without training.
    pub fn phase1_loss(&self, step: usize) -> crate::Result<f32> {
        let s = self.sample(step)?;
        let n = self.normals.len();
        let (w, h) = (self.config.width as usize, self.config.height as usize);
        let plain = self.plain();
        let layers = self.frozen_alphas_of(self.stage1_input_on(&s, &plain)?);
        let inputs = self.render_inputs(&s, &plain)?;
        let (_, mni) = render_shared(
            layers.alpha.clone(),
            layers.colour_or(&inputs.color),
            &inputs.geom,
            inputs.soft.clone(),
        );
        let target = inputs.target.clone().expand([n, 3, h, w]);
        scalar(self.loss.compute(inputs.scored(mni), target)?)
    }

    /// Mean PSNR and (with `lpips`) LPIPS over `count` deterministic validation samples (see
    /// [`Trainer::validation_sample`]): the learned blend, and the Soft heuristic on the same
    /// stage 1.
    pub fn evaluate_scores(
        &self,
        count: usize,
        lpips: Option<&crate::backbone::Backbone>,
    ) -> crate::Result<EvalScores> {
        let mut e = EvalScores::default();
        let plain = self.plain();
        let blend = self.blend.valid();
        for k in 0..count {
            let s = self.validation_sample(k)?;
            let input = self.stage1_input_on(&s, &plain)?;
            let inc_colour = self.inconsistency_colour(&input, &plain);
            let layers = self.frozen_alphas_of(input);
            let inputs = self.render_inputs(&s, &plain)?;
            let inc = inc_colour
                .map(|c| inconsistency_of(layers.alpha.clone(), c, &inputs.geom, &inputs.soft));
            let (soft_img, mni) = render_shared(
                layers.alpha.clone(),
                layers.colour_or(&inputs.color),
                &inputs.geom,
                inputs.soft.clone(),
            );
            let img = learned_blend(&blend, mni, inputs.soft.clone(), inc);
            let target = inputs.target.clone();
            // A run that scores covered pixels is validated on them too: its uncovered pixels
            // are free to drift (no loss there), so whole-image PSNR would mislead.
            let psnr = |x: Tensor<4>| match &inputs.covered {
                Some(m) => psnr_covered(x, target.clone(), m.clone()),
                None => psnr_of(x, target.clone(), false, 1),
            };
            e.psnr_learned += f64::from(psnr(img.clone())?);
            e.psnr_soft += f64::from(psnr(soft_img.clone())?);
            let (img, soft_img) = (inputs.scored(img), inputs.scored(soft_img));
            if let Some(net) = lpips {
                let l = scalar(net.lpips(img.clamp(0.0, 1.0), target.clone()).mean())?;
                let ls = scalar(net.lpips(soft_img.clamp(0.0, 1.0), target).mean())?;
                *e.lpips_learned.get_or_insert(0.0) += f64::from(l);
                *e.lpips_soft.get_or_insert(0.0) += f64::from(ls);
            }
        }
        let k = count.max(1) as f64;
        e.psnr_learned /= k;
        e.psnr_soft /= k;
        e.lpips_learned = e.lpips_learned.map(|v| v / k);
        e.lpips_soft = e.lpips_soft.map(|v| v / k);
        Ok(e)
    }

    /// Mean PSNR over `count` deterministic validation samples: the learned blend, and the Soft
    /// heuristic on the same stage 1.
    pub fn evaluate(&self, count: usize) -> crate::Result<(f64, f64)> {
        let e = self.evaluate_scores(count, None)?;
        Ok((e.psnr_learned, e.psnr_soft))
    }
}

/// Stage 1's alphas, one layer per normal and plane: its output, or with the sweep prior the
/// prior's logits corrected by its output. A colour head's second channel gives each layer its
/// own colour ([`crate::SourceColour`]); without one the layers share the reference's (`None`).
///
/// # Shapes
/// `volume [N, C, D, H, W]` → `([N·D, 1, H, W], Some([N·D, 3, H, W]) or None)`
pub(crate) fn alphas_of(stage1: &Stage1, input: Stage1Input) -> Layers {
    let on_cpu = mhi_kernels::on_cpu_backend(&input.volume.device());
    let Some(prior) = input.prior.as_ref().filter(|_| on_cpu) else {
        return alphas_of_tensors(stage1, input);
    };
    // The CPU backend with the sweep prior: the upsampling and each head in one pass forward
    // and one backward (`heads`), the same values as the tensor operations below.
    let [n, _, d, hs, ws] = input.volume.dims();
    let small = stage1.forward_full(input.volume);
    let part = |k: usize| small.clone().narrow(1, k, 1).reshape([n * d, hs, ws]);
    let alpha = crate::heads::upsampled(part(0), std::sync::Arc::new(prior.head()));
    let colour = match (&input.colour, small.dims()[1]) {
        (Some(sc), 2) => Some(crate::heads::upsampled(
            part(1),
            std::sync::Arc::new(sc.head()),
        )),
        _ => None,
    };
    Layers { alpha, colour }
}

/// [`alphas_of`] as burn tensor operations (any device; without the prior on the CPU too).
pub(crate) fn alphas_of_tensors(stage1: &Stage1, input: Stage1Input) -> Layers {
    let [n, _, d, _, _] = input.volume.dims();
    let (h, w) = input.size;
    let out = stage1.forward_blocks(input.volume, input.size);
    let c = out.dims()[1];
    let alpha = out.clone().narrow(1, 0, 1).reshape([n * d, 1, h, w]);
    let alpha = match input.prior {
        Some(p) => p.apply(alpha),
        None => alpha,
    };
    let colour = match (input.colour, c) {
        (Some(sc), 2) => Some(sc.apply(out.narrow(1, 1, 1).reshape([n * d, 1, h, w]))),
        _ => None,
    };
    Layers { alpha, colour }
}

/// Stage 1's layers: alphas `[N·D, 1, H, W]` and, with a colour head, their colours
/// `[N·D, 3, H, W]`.
pub(crate) struct Layers {
    pub(crate) alpha: Tensor<4>,
    pub(crate) colour: Option<Tensor<4>>,
}

impl Layers {
    /// The colour to render with: the layers' own, else the shared `reference` `[1, 3, H, W]`.
    fn colour_or(&self, reference: &Tensor<4>) -> Tensor<4> {
        self.colour.clone().unwrap_or_else(|| reference.clone())
    }

    /// The same tensors on the autodiff device (constants there).
    fn autodiff(self) -> Self {
        Self {
            alpha: self.alpha.autodiff(),
            colour: self.colour.map(|t| t.autodiff()),
        }
    }
}

/// Each normal's photo-inconsistency seen from the target, the mean over RGB of the
/// multi-normal images of the inconsistency layers `colour` (a constant: no gradient).
///
/// # Shapes
/// `alpha` `[N·D, 1, H, W]`, `colour` `[N·D, 3, H, W]` → `[1, N, H, W]`
fn inconsistency_of(
    alpha: Tensor<4>,
    colour: Tensor<4>,
    geom: &WarpGeometry,
    soft: &Tensor<4>,
) -> Tensor<4> {
    let (_, mni) = render_shared(alpha.detach(), colour, geom, soft.clone());
    let [n, _, h, w] = mni.dims();
    mni.detach().mean_dim(1).reshape([1, n, h, w])
}

/// The multi-normal images blended consistently (as `render`'s default blend:
/// [`mhi_render::consistent_weights`]), the weights held constant: the gradient reaches each
/// normal's image in proportion to its weight.
///
/// # Shapes
/// `mni`: `[N, 3, H, W]`, `soft`: `[N, 1, H, W]`, `inc`: `[1, N, H, W]` → `[1, 3, H, W]`
fn consistent_blend(mni: Tensor<4>, soft: Tensor<4>, inc: Tensor<4>, beta: f32) -> Tensor<4> {
    let [n, _, h, w] = mni.dims();
    let c = inc.reshape([n, 1, h, w]).detach();
    let lowest = c.clone().min_dim(0);
    let scaled = soft.detach() * (c - lowest).mul_scalar(-beta).exp();
    let weights = scaled.clone() / scaled.sum_dim(0);
    mhi_render::diff::blend(mni, weights.detach())
}

/// Stage 2: the blending network's weights applied to the multi-normal images.
///
/// # Shapes
/// `mni`: `[N, 3, H, W]`, `soft`: `[N, 1, H, W]`, `inc` (for a network that reads it)
/// `[1, N, H, W]` → `[1, 3, H, W]`
fn learned_blend(
    blend: &BlendNet,
    mni: Tensor<4>,
    soft: Tensor<4>,
    inc: Option<Tensor<4>>,
) -> Tensor<4> {
    let [n, _, h, w] = mni.dims();
    let mut parts = vec![
        mni.clone().reshape([1, 3 * n, h, w]),
        soft.reshape([1, n, h, w]),
    ];
    parts.extend(inc);
    let input = Tensor::cat(parts, 1);
    let weights = blend.forward(input).reshape([n, 1, h, w]);
    mhi_render::diff::blend(mni, weights)
}

/// Held-out scores of a model (see [`Trainer::evaluate_scores`]).
#[derive(Debug, Clone, Copy, Default, Serialize, Deserialize)]
pub struct EvalScores {
    /// PSNR (dB) of the learned blend.
    pub psnr_learned: f64,
    /// PSNR (dB) of the Soft heuristic on the same stage 1.
    pub psnr_soft: f64,
    /// LPIPS-alex of the learned blend, when the weights were given.
    pub lpips_learned: Option<f64>,
    /// LPIPS-alex of the Soft heuristic.
    pub lpips_soft: Option<f64>,
}

struct RenderInputs {
    geom: WarpGeometry,
    color: Tensor<4>,
    soft: Tensor<4>,
    target: Tensor<4>,
    /// `[1, 1, H, W]`, 1 where the reference covers the target (with `covered_loss`).
    covered: Option<Tensor<4>>,
}

impl RenderInputs {
    /// What the loss sees of `output` (`[B, 3, H, W]`): itself, or with a coverage mask the
    /// target in the pixels the reference does not cover (no error, no gradient there).
    fn scored(&self, output: Tensor<4>) -> Tensor<4> {
        match &self.covered {
            None => output,
            Some(m) => {
                let dims = output.dims();
                let m = m.clone().expand([dims[0], 1, dims[2], dims[3]]);
                let t = self.target.clone().expand(dims);
                output * m.clone() + t * (m.ones_like() - m)
            }
        }
    }
}

/// Header of `log.csv`.
pub const CSV_HEADER: &str =
    "step,phase,loss,psnr,elapsed_s,volume_ms,stage1_ms,render_ms,loss_ms,backward_ms\n";

/// Header of `val.csv`: held-out PSNR (learned blend, Soft on stage 1) at each checkpoint,
/// over the covered pixels for a run with `covered_loss`.
pub const VAL_CSV_HEADER: &str = "step,elapsed_s,psnr_learned,psnr_soft\n";

#[derive(Debug, Clone, Serialize, Deserialize)]
struct CheckpointState {
    step: usize,
    elapsed_s: f64,
    /// [`TrainConfig::fingerprint`] of the run that wrote it (absent in older checkpoints).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    config_fingerprint: Option<String>,
}

/// The two networks of the checkpoint directory `ck` (`stage1.bpk`, `blend.bpk`), shaped by
/// `config`.
pub(crate) fn load_networks(
    config: &TrainConfig,
    ck: &Path,
    device: &Device,
) -> crate::Result<(Stage1, BlendNet)> {
    let load = |what: &str| ck.join(format!("{what}.bpk"));
    let state_path = ck.join("state.json");
    if let Ok(text) = std::fs::read_to_string(&state_path)
        && let Ok(state) = serde_json::from_str::<CheckpointState>(&text)
        && let Some(f) = state.config_fingerprint
        && f != config.fingerprint()
    {
        return Err(Error::Checkpoint(format!(
            "{}: does not match this run's config.json: it was written by a run with another configuration (fingerprint {f}, this config.json's {}), so its weights would load but mean something else; was config.json edited, or does the checkpoint come from another run?",
            ck.display(),
            config.fingerprint()
        )));
    }
    let stage1 = config
        .stage1
        .init(device)
        .try_load_file(load("stage1"))
        .map_err(|e| record_error(&load("stage1"), &e))?;
    let blend = config
        .blend
        .init(device)
        .try_load_file(load("blend"))
        .map_err(|e| record_error(&load("blend"), &e))?;
    Ok((stage1, blend))
}

/// A checkpoint that cannot be applied, in one paragraph: the first mismatching parameter and how
/// many others there are (burn lists every one).
fn record_error(path: &Path, e: &burn::store::RecordError) -> Error {
    let text = e.to_string();
    let items: Vec<&str> = text
        .split_once('[')
        .map(|(_, rest)| rest.trim_end_matches(']').split("\", \"").collect())
        .unwrap_or_default();
    let msg = match items.as_slice() {
        [first, rest @ ..] if text.contains("mismatch") => format!(
            "does not match this run's config.json ({} parameter(s) differ; first: {}); was config.json edited, or does the checkpoint come from another run?",
            rest.len() + 1,
            first.trim_matches('"')
        ),
        _ => text,
    };
    Error::Checkpoint(format!("{}: {msg}", path.display()))
}

/// burn draws initial weights lazily from one process-wide RNG, so two models built in parallel
/// (or a forward pass in between) would change each other's weights. This lock, the seed and an
/// immediate read of every parameter make the initial weights a function of the seed alone.
static INIT_LOCK: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// The initial networks of `config`, deterministic for its seed.
pub fn init_models(config: &TrainConfig, device: &Device) -> (Stage1, BlendNet) {
    let _guard = INIT_LOCK.lock().unwrap_or_else(|e| e.into_inner());
    device.seed(config.seed);
    let stage1 = materialize(config.stage1.init(device));
    let blend = materialize(config.blend.init(device));
    (stage1, blend)
}

fn materialize<M: Module>(m: M) -> M {
    let record = m.clone().into_record();
    m.load_record(record)
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

fn scalar(t: Tensor<1>) -> crate::Result<f32> {
    let v: Vec<f32> = t
        .into_data()
        .try_to_vec()
        .map_err(|e| Error::NonFinite(format!("cannot read loss: {e:?}")))?;
    v.first()
        .copied()
        .ok_or_else(|| Error::NonFinite("empty loss".into()))
}

/// PSNR over the pixels where `mask` (`[1, 1, H, W]`) is 1, of `output` (`[1, 3, H, W]`)
/// against `target` (over the whole image when nothing is covered).
fn psnr_covered(output: Tensor<4>, target: Tensor<4>, mask: Tensor<4>) -> crate::Result<f32> {
    let [_, c, h, w] = output.dims();
    let m = mask.expand([1, c, h, w]);
    let sq = (output.clone().clamp(0.0, 1.0) - target.clone()).powi_scalar(2) * m.clone();
    let (num, den) = (scalar(sq.sum())?, scalar(m.sum())?);
    if den <= 0.0 {
        return psnr_of(output, target, false, 1);
    }
    Ok(10.0 * (1.0 / (num / den).max(1e-10)).log10())
}

/// PSNR of `output` (`[N or 1, 3, H, W]`) against `target` (`[1, 3, H, W]`), averaged over the
/// N images when `per_normal`.
fn psnr_of(output: Tensor<4>, target: Tensor<4>, per_normal: bool, n: usize) -> crate::Result<f32> {
    let [b, c, h, w] = output.dims();
    let target = if per_normal {
        target.expand([n, c, h, w])
    } else {
        target
    };
    let diff = (output.clamp(0.0, 1.0) - target).powi_scalar(2);
    let mse: Vec<f32> = diff
        .reshape([b, c * h * w])
        .mean_dim(1)
        .into_data()
        .try_to_vec()
        .map_err(|e| Error::NonFinite(format!("{e:?}")))?;
    let p: f32 = mse
        .iter()
        .map(|m| 10.0 * (1.0 / m.max(1e-10)).log10())
        .sum::<f32>()
        / b as f32;
    Ok(p)
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::tensor::TensorData;
    use image::Rgb32FImage;

    /// What stage 1 learns from with `stage1_consistent_loss` is the image `render` makes by
    /// default: the multi-normal images blended by [`mhi_render::consistent_weights`].
    #[test]
    fn the_training_blend_is_the_render_blend() {
        let (n, h, w) = (3, 5, 7);
        let px = h * w;
        let v = |i: usize, k: usize| ((i * 7919 + k * 104_729) % 1000) as f32 / 999.0;
        let mut soft: Vec<f32> = (0..n * px).map(|i| 0.1 + v(i, 1)).collect();
        for p in 0..px {
            let s: f32 = (0..n).map(|k| soft[k * px + p]).sum();
            (0..n).for_each(|k| soft[k * px + p] /= s);
        }
        let inc: Vec<f32> = (0..n * px).map(|i| 0.3 * v(i, 2)).collect();
        let mni: Vec<f32> = (0..n * 3 * px).map(|i| v(i, 3)).collect();
        let device = Device::flex();
        let t = |data: &[f32], shape: [usize; 4]| {
            Tensor::<4>::from_data(TensorData::new(data.to_vec(), shape), &device)
        };
        let got = consistent_blend(
            t(&mni, [n, 3, h, w]),
            t(&soft, [n, 1, h, w]),
            t(&inc, [1, n, h, w]),
            20.0,
        );
        let got: Vec<f32> = got.into_data().try_to_vec::<f32>().unwrap();
        // The same through the renderer's functions on images (RGB interleaved).
        let image = |f: &dyn Fn(usize, usize) -> f32| {
            Rgb32FImage::from_fn(w as u32, h as u32, |x, y| {
                let p = y as usize * w + x as usize;
                image::Rgb([f(0, p), f(1, p), f(2, p)])
            })
        };
        let inc_images: Vec<Rgb32FImage> = (0..n).map(|k| image(&|_, p| inc[k * px + p])).collect();
        let mni_images: Vec<Rgb32FImage> = (0..n)
            .map(|k| image(&|c, p| mni[(k * 3 + c) * px + p]))
            .collect();
        let weights = mhi_render::consistent_weights(&soft, &inc_images, 20.0).unwrap();
        let want = mhi_render::combine(&mni_images, &weights);
        let mut worst = 0.0_f32;
        for p in 0..px {
            for c in 0..3 {
                let a = got[c * px + p];
                let b = want.as_raw()[3 * p + c];
                worst = worst.max((a - b).abs());
            }
        }
        assert!(worst < 1e-5, "training blend − render blend: {worst}");
        // And it is not Soft's blend: the inconsistencies moved the weights.
        let soft_image = mhi_render::combine(&mni_images, &soft);
        let apart = soft_image
            .as_raw()
            .iter()
            .zip(want.as_raw())
            .map(|(a, b)| (a - b).abs())
            .fold(0.0_f32, f32::max);
        assert!(apart > 1e-2, "{apart}");
    }
}
