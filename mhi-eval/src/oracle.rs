//! The oracle study on synthetic scenes (`cargo xtask oracle` is [`oracle`] with its options
//! parsed): MHIs and MPIs built from the exact geometry, rendered into target views; PSNR per
//! rotation bin, exact against pruned, and the best normal per pixel chosen with the truth (an
//! upper bound of what a blend can gain).

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use clap::Args;
use glam::DVec3;
use image::Rgb32FImage;
use mhi_data::{Dataset, Fit, RotationBin, load_frame, load_scene};
use mhi_geom::{BlendHeuristic, Camera, NormalSet, depths_linear_in_disparity};
use mhi_net::{MhiSource, ViewSynthesis};
use mhi_render::{Blend, Prune, RenderOptions, SweepConfig, oracle_weights, render};
use serde::Serialize;

use crate::images::save_png;
use crate::support::{ensure_synthetic, staged, truth_of};

/// Options of `cargo xtask oracle`.
#[derive(Args, Debug, Clone)]
pub struct OracleArgs {
    /// Synthetic dataset root (generated with the default `synth` settings if it has no test split).
    #[arg(long, default_value = "data/synth")]
    pub data: PathBuf,
    /// Triplets per test sequence.
    #[arg(long, default_value_t = 4)]
    pub per_sequence: usize,
    /// Seed of the triplet draw.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Output directory for report.json and sample images.
    #[arg(long, default_value = "out/oracle")]
    pub out: PathBuf,
}

/// One configuration of the oracle experiment.
struct Config {
    name: String,
    normals: NormalSet,
    depths: Vec<f64>,
    blend: OracleBlend,
    sweep: bool,
}

#[derive(Clone, Copy)]
enum OracleBlend {
    /// One-hot on the normal closest in angle to the true surface normal.
    Oracle,
    /// Per pixel, the multi-normal image closest to the ground truth: an upper bound of any
    /// blending, learned or not.
    BestNormal,
    Heuristic(BlendHeuristic),
}

#[derive(Default, Serialize, Clone)]
struct Acc {
    count: usize,
    psnr: f64,
    psnr_covered: f64,
    ssim: f64,
    ms: f64,
    pruned_psnr: f64,
    pruned_ms: f64,
}

impl Acc {
    fn add(&mut self, o: &Acc) {
        self.count += o.count;
        self.psnr += o.psnr;
        self.psnr_covered += o.psnr_covered;
        self.ssim += o.ssim;
        self.ms += o.ms;
        self.pruned_psnr += o.pruned_psnr;
        self.pruned_ms += o.pruned_ms;
    }

    fn row(&self, method: &str, bin: &str) -> Row {
        let k = self.count as f64;
        Row {
            method: method.into(),
            bin: bin.into(),
            count: self.count,
            psnr: self.psnr / k,
            psnr_covered: self.psnr_covered / k,
            ssim: self.ssim / k,
            ms_per_view: self.ms / k,
            pruned_psnr: self.pruned_psnr / k,
            pruned_ms_per_view: self.pruned_ms / k,
        }
    }
}

#[derive(Serialize)]
struct Row {
    method: String,
    bin: String,
    count: usize,
    psnr: f64,
    /// PSNR over the target pixels whose surface point the reference view sees.
    psnr_covered: f64,
    ssim: f64,
    ms_per_view: f64,
    pruned_psnr: f64,
    pruned_ms_per_view: f64,
}

/// `cargo xtask oracle`.
pub fn oracle(a: &OracleArgs) -> anyhow::Result<()> {
    staged(&a.out, "oracle report", |out| {
        let mut a = a.clone();
        a.out = out.to_path_buf();
        oracle_into(&a)
    })?;
    println!("report: {}", a.out.join("report.json").display());
    Ok(())
}

/// The oracle study's configurations: the oracle MHI with its three blends, the oracle MPI at
/// D = 32 and 160, and the sweep MHI.
fn oracle_configs() -> anyhow::Result<Vec<Config>> {
    let d32 = depths_linear_in_disparity(1.0, 100.0, 32)?;
    let d160 = depths_linear_in_disparity(1.0, 100.0, 160)?;
    Ok(vec![
        Config {
            name: "oracle MHI N=5 D=32".into(),
            normals: NormalSet::paper(),
            depths: d32.clone(),
            blend: OracleBlend::Oracle,
            sweep: false,
        },
        Config {
            name: "oracle MHI N=5 D=32 best".into(),
            normals: NormalSet::paper(),
            depths: d32.clone(),
            blend: OracleBlend::BestNormal,
            sweep: false,
        },
        Config {
            name: "oracle MHI N=5 D=32 soft".into(),
            normals: NormalSet::paper(),
            depths: d32.clone(),
            blend: OracleBlend::Heuristic(BlendHeuristic::Soft),
            sweep: false,
        },
        Config {
            name: "oracle MPI N=1 D=32".into(),
            normals: NormalSet::paper_subset(1)?,
            depths: d32.clone(),
            blend: OracleBlend::Oracle,
            sweep: false,
        },
        Config {
            name: "oracle MPI N=1 D=160".into(),
            normals: NormalSet::paper_subset(1)?,
            depths: d160,
            blend: OracleBlend::Oracle,
            sweep: false,
        },
        Config {
            name: "sweep MHI N=5 D=32 soft".into(),
            normals: NormalSet::paper(),
            depths: d32,
            blend: OracleBlend::Heuristic(BlendHeuristic::Soft),
            sweep: true,
        },
    ])
}

/// The oracle study's table: mean PSNR per rotation bin (count), covered PSNR, times and what
/// pruning changed.
fn print_oracle_table(rows: &[Row], configs: &[Config], triplets: usize, scenes: usize) {
    println!(
        "{} triplets from {} test scenes; mean PSNR (dB) per rotation bin (count):",
        triplets, scenes
    );
    let bins: Vec<String> = RotationBin::ALL
        .iter()
        .map(|b| b.label().to_string())
        .chain(["all".to_string()])
        .collect();
    print!("{:<26}", "method");
    for b in &bins {
        print!("{:>16}", b);
    }
    println!(
        "{:>14}{:>12}{:>14}{:>14}",
        "covered PSNR", "ms/view", "pruned ms", "pruned ΔPSNR"
    );
    for c in configs {
        print!("{:<26}", c.name);
        for b in &bins {
            match rows.iter().find(|r| r.method == c.name && &r.bin == b) {
                Some(r) => print!("{:>10.2} ({:>3})", r.psnr, r.count),
                None => print!("{:>16}", "-"),
            }
        }
        if let Some(r) = rows.iter().find(|r| r.method == c.name && r.bin == "all") {
            println!(
                "{:>14.2}{:>12.1}{:>14.1}{:>+14.4}",
                r.psnr_covered,
                r.ms_per_view,
                r.pruned_ms_per_view,
                r.pruned_psnr - r.psnr
            );
        }
    }
}

fn oracle_into(a: &OracleArgs) -> anyhow::Result<()> {
    ensure_synthetic(&a.data)?;
    let ds = Dataset::open(&a.data, "test", 3)?;
    let index = crate::support::sample_index(&ds, a.per_sequence, a.seed)?;
    let configs = oracle_configs()?;
    let mut acc: BTreeMap<(usize, RotationBin), Acc> = BTreeMap::new();
    let pb = crate::progress::bar(index.triplets.len() as u64, "oracle");
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("cannot create {}", a.out.display()))?;
    for (ti, t) in index.triplets.iter().enumerate() {
        let seq = ds
            .sequence(&t.sequence)
            .context("triplet sequence vanished")?;
        let scene_path = ds.dir.join(&seq.name).join("scene.json");
        let scene = load_scene(&scene_path)?;
        let rf = load_frame(&seq.frames[t.reference], None, Fit::Stretch)?;
        let sf = load_frame(&seq.frames[t.source], None, Fit::Stretch)?;
        let tf = load_frame(&seq.frames[t.target], None, Fit::Stretch)?;
        let ref_truth = truth_of(&scene, &rf.camera);
        let ref_from_tgt = rf.camera.from_other(&tf.camera);
        let tgt_normals: Vec<Option<DVec3>> = scene
            .ground_truth(&tf.camera)
            .into_iter()
            .map(|g| g.map(|(n, _)| ref_from_tgt.transform_vector(n)))
            .collect();
        let covered = covered_mask(&scene, &rf.camera, &tf.camera);
        for (ci, c) in configs.iter().enumerate() {
            let source = if c.sweep {
                MhiSource::Sweep {
                    normals: c.normals.clone(),
                    depths: c.depths.clone(),
                    config: SweepConfig::for_short_side(rf.image.width().min(rf.image.height())),
                }
            } else {
                MhiSource::Oracle {
                    normals: c.normals.clone(),
                    depths: c.depths.clone(),
                    truth: &ref_truth,
                }
            };
            let (mhi, _) = ViewSynthesis::new(source).mhi(&rf, &sf)?;
            let w;
            let blend = match c.blend {
                OracleBlend::Oracle => {
                    w = oracle_weights(&c.normals, &tgt_normals);
                    Blend::Weights(&w)
                }
                OracleBlend::Heuristic(h) => Blend::Heuristic(h),
                OracleBlend::BestNormal => Blend::Heuristic(BlendHeuristic::Avg),
            };
            let keep_multi_normal = matches!(c.blend, OracleBlend::BestNormal);
            let t0 = Instant::now();
            let mut full = render(
                &mhi,
                &tf.camera,
                &RenderOptions {
                    blend,
                    keep_multi_normal,
                    ..Default::default()
                },
            )?;
            let ms = t0.elapsed().as_secs_f64() * 1e3;
            if keep_multi_normal {
                full.image = best_per_pixel(&full.multi_normal, &tf.image);
            }
            let t1 = Instant::now();
            let mut pruned = render(
                &mhi,
                &tf.camera,
                &RenderOptions {
                    blend,
                    keep_multi_normal,
                    prune: Prune::DEFAULT,
                },
            )?;
            let pruned_ms = t1.elapsed().as_secs_f64() * 1e3;
            if keep_multi_normal {
                pruned.image = best_per_pixel(&pruned.multi_normal, &tf.image);
            }
            let e = acc.entry((ci, t.bin)).or_default();
            e.count += 1;
            e.psnr += crate::psnr(&full.image, &tf.image)?;
            e.psnr_covered +=
                crate::psnr_masked(&full.image, &tf.image, &covered)?.unwrap_or(crate::MAX_PSNR);
            e.ssim += crate::ssim(&full.image, &tf.image)?;
            e.ms += ms;
            e.pruned_psnr += crate::psnr(&pruned.image, &tf.image)?;
            e.pruned_ms += pruned_ms;
            if ti == 0 {
                let name = c.name.replace([' ', '='], "_");
                save_png(&a.out.join(format!("sample_{name}.png")), &full.image)?;
                if ci == 0 {
                    save_png(&a.out.join("sample_ground_truth.png"), &tf.image)?;
                    save_png(&a.out.join("sample_reference.png"), &rf.image)?;
                }
            }
        }
        pb.inc(1);
    }
    pb.finish_and_clear();
    let mut rows = Vec::new();
    let mut all: BTreeMap<usize, Acc> = BTreeMap::new();
    for ((ci, bin), e) in &acc {
        rows.push(e.row(&configs[*ci].name, bin.label()));
        all.entry(*ci).or_default().add(e);
    }
    for (ci, e) in &all {
        rows.push(e.row(&configs[*ci].name, "all"));
    }
    print_oracle_table(&rows, &configs, index.triplets.len(), ds.sequences.len());
    let json = serde_json::to_vec_pretty(&rows)?;
    mhi_data::write_atomic(&a.out.join("report.json"), &json)?;
    Ok(())
}

/// Target pixels whose surface point lies inside the reference image and is visible from it.
fn covered_mask(scene: &mhi_data::Scene, reference: &Camera, target: &Camera) -> Vec<bool> {
    let world_from_tgt = target.cam_from_world.inverse();
    let origin = world_from_tgt.translation();
    let ref_center = reference.center_in_world();
    (0..target.height)
        .flat_map(|y| (0..target.width).map(move |x| (x, y)))
        .map(|(x, y)| {
            let dir = world_from_tgt
                .transform_vector(target.intrinsics.ray(mhi_geom::pixel_center(x, y)));
            let Some(hit) = scene.trace(origin, dir) else {
                return false;
            };
            let p = origin + dir * hit.s;
            let seen = scene
                .trace(ref_center, p - ref_center)
                .is_some_and(|h| (h.s - 1.0).abs() < 1e-6);
            seen && reference
                .project_world(p)
                .is_some_and(|u| reference.contains(u))
        })
        .collect()
}

/// Per pixel, the candidate image closest to the ground truth.
fn best_per_pixel(candidates: &[Rgb32FImage], truth: &Rgb32FImage) -> Rgb32FImage {
    Rgb32FImage::from_fn(truth.width(), truth.height(), |x, y| {
        let t = truth.get_pixel(x, y).0;
        let err = |c: &Rgb32FImage| {
            let p = c.get_pixel(x, y).0;
            (0..3).map(|k| (p[k] - t[k]).powi(2)).sum::<f32>()
        };
        let best = candidates
            .iter()
            .min_by(|a, b| err(a).total_cmp(&err(b)))
            .expect("at least one normal");
        *best.get_pixel(x, y)
    })
}
