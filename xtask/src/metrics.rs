//! `cargo xtask metrics A.png B.png`: PSNR, SSIM, LPIPS-alex and LPIPS-vgg of two images.

use std::path::PathBuf;

use anyhow::{Context, bail};
use burn::tensor::Device;
use clap::Args;
use mhi_net::backbone::{Backbone, Net};

/// Options of `cargo xtask metrics`.
#[derive(Args, Debug)]
pub struct MetricsArgs {
    /// First image.
    pub a: PathBuf,
    /// Second image (same size).
    pub b: PathBuf,
    /// Weights cache (default: $MHI_CACHE, else ~/.cache/mhi); see `cargo xtask weights`.
    #[arg(long)]
    pub cache: Option<PathBuf>,
}

/// `cargo xtask metrics`.
pub fn metrics(a: &MetricsArgs) -> anyhow::Result<()> {
    let load = |p: &PathBuf| -> anyhow::Result<image::Rgb32FImage> {
        Ok(mhi_data::to_f32(&mhi_data::read_rgb(p)?))
    };
    let (x, y) = (load(&a.a)?, load(&a.b)?);
    if x.dimensions() != y.dimensions() {
        bail!(
            "{} is {}x{} but {} is {}x{}: the metrics compare images of the same size",
            a.a.display(),
            x.width(),
            x.height(),
            a.b.display(),
            y.width(),
            y.height()
        );
    }
    println!("PSNR       {:.4} dB", mhi_eval::psnr(&x, &y)?);
    match mhi_eval::ssim(&x, &y) {
        Ok(s) => println!("SSIM       {s:.5}"),
        Err(e) => println!("SSIM       n/a ({e})"),
    }
    let dir = crate::common::cache_dir(a.cache.as_deref()).join("weights");
    let device = Device::flex();
    let tx = mhi_render::diff::image_to_tensor(&x, &device);
    let ty = mhi_render::diff::image_to_tensor(&y, &device);
    for (name, net) in [("LPIPS-alex", Net::Alex), ("LPIPS-vgg", Net::Vgg16)] {
        let m = net.min_side();
        if x.width() < m || x.height() < m {
            println!(
                "{name:<10} n/a (needs at least {m}x{m} pixels; the images are {}x{})",
                x.width(),
                x.height()
            );
            continue;
        }
        let bb = Backbone::load(&dir, net, &device).with_context(|| {
            format!("{name} needs the pretrained weights (`cargo xtask weights` fetches them)")
        })?;
        let v: Vec<f32> = bb
            .lpips(tx.clone(), ty.clone())
            .into_data()
            .try_to_vec()
            .map_err(|e| anyhow::anyhow!("{e:?}"))?;
        match v.first() {
            Some(l) if l.is_finite() => println!("{name:<10} {l:.4}"),
            other => bail!(
                "{name} of {} and {} is {other:?}",
                a.a.display(),
                a.b.display()
            ),
        }
    }
    Ok(())
}
