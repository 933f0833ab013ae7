//! `cargo xtask bench --scaling`: how the time of one view grows with image size, planes,
//! normals and threads, for the CPU renderer, the training-free sweep and the learned model's
//! inference; a CSV, log-log figures and the fitted exponent of each series.

use std::fmt::Write as _;
use std::path::Path;

use crate::plot::{Axes, Curve};
use burn::tensor::Device;
use glam::DVec3;
use image::Rgb32FImage;
use mhi_data::LoadedFrame;
use mhi_geom::{BlendHeuristic, Camera, NormalSet, depths_linear_in_disparity};
use mhi_net::{BlendChoice, MhiSource, Model, TrainConfig, ViewSynthesis};
use mhi_render::{Blend, Prune, RenderOptions, SweepConfig, render};
use rand::{Rng, SeedableRng};

use super::median_ms;

/// `n` unit normals: the paper's sets for 1, 2, 3 and 5, else `n` normals tilted 40° from the
/// optical axis, evenly around it.
fn normals(n: usize) -> anyhow::Result<NormalSet> {
    if matches!(n, 1 | 2 | 3 | 5) {
        return Ok(NormalSet::paper_subset(n)?);
    }
    let t = 40f64.to_radians();
    Ok(NormalSet::custom(
        (0..n)
            .map(|k| {
                let a = std::f64::consts::TAU * k as f64 / n as f64;
                DVec3::new(t.sin() * a.cos(), t.sin() * a.sin(), t.cos())
            })
            .collect(),
    )?)
}

/// A reference and a target camera of the bench (4° apart) at `size`, and random images.
fn pair(size: u32) -> anyhow::Result<(LoadedFrame, LoadedFrame, Camera)> {
    let (mhi, target) = super::scene(1, 1, size, false)?;
    let reference = *mhi.reference();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    let mut img = || {
        Rgb32FImage::from_fn(size, size, |_, _| {
            image::Rgb([rng.random(), rng.random(), rng.random()])
        })
    };
    let rf = LoadedFrame {
        image: img(),
        camera: reference,
    };
    // The source sits where the target is; the view rendered is the target (the time is what
    // matters here, not the picture).
    let sf = LoadedFrame {
        image: img(),
        camera: target,
    };
    Ok((rf, sf, target))
}

#[derive(Clone, Copy, PartialEq)]
enum What {
    Render,
    Sweep,
    Learned,
}

impl What {
    fn name(self) -> &'static str {
        match self {
            What::Render => "render (N×D MHI → view, Soft)",
            What::Sweep => "training-free sweep (MHI + view)",
            What::Learned => "learned inference (cost volume → view)",
        }
    }
}

/// Milliseconds of one view of `what` at (size, N, D) on `threads` threads.
fn time_one(
    what: What,
    size: u32,
    n: usize,
    d: usize,
    threads: usize,
    runs: usize,
) -> anyhow::Result<f64> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()?;
    let (rf, sf, target) = pair(size)?;
    let normals = normals(n)?;
    let depths = depths_linear_in_disparity(1.0, 100.0, d)?;
    let soft = RenderOptions {
        blend: Blend::Heuristic(BlendHeuristic::Soft),
        ..Default::default()
    };
    pool.install(|| -> anyhow::Result<f64> {
        Ok(match what {
            What::Render => {
                let (mhi, target) = super::scene_with(normals, d, size)?;
                median_ms(runs, || {
                    std::hint::black_box(render(&mhi, &target, &soft).expect("bench scene"));
                })
            }
            What::Sweep => {
                let synth = ViewSynthesis::new(MhiSource::Sweep {
                    normals,
                    depths,
                    config: SweepConfig::default(),
                });
                median_ms(runs, || {
                    let (mhi, _) = synth.mhi(&rf, &sf).expect("bench pair");
                    std::hint::black_box(render(&mhi, &target, &soft).expect("bench scene"));
                })
            }
            What::Learned => {
                let mut config = TrainConfig::for_normals(n);
                config.planes = d;
                let model = Model::untrained(config, Device::flex())?;
                let synth = ViewSynthesis::new(MhiSource::Learned(&model));
                median_ms(runs, || {
                    let (mhi, _) = synth.mhi(&rf, &sf).expect("bench pair");
                    std::hint::black_box(
                        synth
                            .render(&mhi, &target, BlendChoice::Learned, Prune::NONE)
                            .expect("bench scene"),
                    );
                })
            }
        })
    })
}

/// Least-squares slope of log(ms) against log(x): the exponent of a power law.
pub fn exponent(points: &[(f64, f64)]) -> f64 {
    let pts: Vec<(f64, f64)> = points
        .iter()
        .filter(|(x, y)| *x > 0.0 && *y > 0.0)
        .map(|(x, y)| (x.ln(), y.ln()))
        .collect();
    let n = pts.len() as f64;
    if pts.len() < 2 {
        return f64::NAN;
    }
    let (mx, my) = (
        pts.iter().map(|p| p.0).sum::<f64>() / n,
        pts.iter().map(|p| p.1).sum::<f64>() / n,
    );
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    sxy / sxx
}

/// Run every series, write `scaling.csv` and `scaling_{size,planes,normals,threads}.svg/.png`
/// into `out`, print the exponents; return them as JSON.
pub fn scaling(out: &Path, runs: usize) -> anyhow::Result<serde_json::Value> {
    std::fs::create_dir_all(out)?;
    // (axis, x label, the (size, N, D, threads) of each point, x of each point)
    type Point = (u32, usize, usize, usize);
    let axes: [(&str, &str, Vec<Point>); 4] = [
        (
            "size",
            "pixels per view (log)",
            [64, 128, 256, 512, 1024]
                .iter()
                .map(|&s| (s, 5, 32, 2))
                .collect(),
        ),
        (
            "planes",
            "planes per normal D (log)",
            [8, 16, 32, 64, 128]
                .iter()
                .map(|&d| (256, 5, d, 2))
                .collect(),
        ),
        (
            "normals",
            "normals N (log)",
            [1, 2, 3, 5, 7, 9]
                .iter()
                .map(|&n| (256, n, 32, 2))
                .collect(),
        ),
        (
            "threads",
            "threads (log)",
            [1, 2].iter().map(|&t| (256, 5, 32, t)).collect(),
        ),
    ];
    let mut csv = String::from("series,axis,size,normals,planes,threads,x,ms\n");
    let mut fits = serde_json::Map::new();
    let total: usize = axes.iter().map(|a| a.2.len() * 3).sum();
    let pb = crate::progress::bar(total as u64, "scaling");
    for (axis, xlabel, points) in &axes {
        let mut curves = Vec::new();
        for what in [What::Render, What::Sweep, What::Learned] {
            let mut series = Vec::new();
            for &(size, n, d, t) in points {
                pb.inc(1);
                // The learned model's 3D U-Net and the sweep's volume grow as N·D·pixels:
                // keep them to sizes this machine renders in seconds.
                // The learned model exists for the paper's normal sets only.
                let too_big = match what {
                    What::Render => false,
                    What::Sweep => size > 512 || d > 64,
                    What::Learned => size > 512 || d > 32 || !matches!(n, 1 | 2 | 3 | 5),
                };
                if too_big {
                    continue;
                }
                let ms = time_one(what, size, n, d, t, runs)?;
                let x = match *axis {
                    "size" => f64::from(size) * f64::from(size),
                    "planes" => d as f64,
                    "normals" => n as f64,
                    _ => t as f64,
                };
                let _ = writeln!(csv, "{},{axis},{size},{n},{d},{t},{x},{ms:.3}", what.name());
                series.push((x, ms));
            }
            let e = exponent(&series);
            println!("{:<42} vs {axis:<8}: time ∝ x^{e:.2}", what.name());
            fits.insert(format!("{}|{axis}", what.name()), serde_json::json!(e));
            curves.push(Curve {
                label: format!("{} (exponent {e:.2})", what.name()),
                points: series,
            });
        }
        crate::plot::lines(
            &out.join(format!("scaling_{axis}")),
            &curves,
            &format!("time per view against {axis} (log-log; slope = exponent)"),
            &Axes {
                x: xlabel,
                y: "ms per view (log)",
                log: true,
            },
        )?;
    }
    pb.finish_and_clear();
    mhi_data::write_atomic(&out.join("scaling.csv"), csv.as_bytes())?;
    println!(
        "wrote {} and scaling_*.svg/png",
        out.join("scaling.csv").display()
    );
    Ok(serde_json::Value::Object(fits))
}

#[cfg(test)]
mod tests {
    #[test]
    fn exponent_of_a_power_law() {
        let p: Vec<(f64, f64)> = (1..6)
            .map(|k| (k as f64, 3.0 * (k as f64).powf(1.5)))
            .collect();
        assert!((super::exponent(&p) - 1.5).abs() < 1e-12);
        assert!(super::exponent(&p[..1]).is_nan());
    }
}
