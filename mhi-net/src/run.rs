//! A training run's directory: the one place that knows its layout — `config.json`,
//! `latest.json` (which checkpoint is current), `ckpt-NNNNNNN/`, `log.csv` (one row per step),
//! `val.csv` (one row per checkpoint) and `summary.json` (the closing scores).

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::Error;
use crate::config::TrainConfig;

/// Which checkpoint of a run is current (`latest.json`).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Latest {
    /// Steps behind it.
    pub step: usize,
    /// Its directory, relative to the run.
    pub dir: String,
}

/// One row of `val.csv`: held-out PSNR at a checkpoint.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ValRow {
    /// Training steps so far.
    pub step: usize,
    /// Training wall-clock seconds so far.
    pub elapsed_s: f64,
    /// PSNR (dB) of the learned blend (over covered pixels for a run with `covered_loss`).
    pub psnr_learned: f64,
    /// PSNR (dB) of the Soft heuristic on the same stage 1.
    pub psnr_soft: f64,
}

/// A run directory.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RunDir {
    path: PathBuf,
}

impl RunDir {
    /// The run in `path` (nothing is read yet).
    pub fn new(path: impl Into<PathBuf>) -> Self {
        Self { path: path.into() }
    }
    /// The directory.
    pub fn path(&self) -> &Path {
        &self.path
    }
    /// `config.json`.
    pub fn config_path(&self) -> PathBuf {
        self.path.join("config.json")
    }
    /// `latest.json`.
    pub fn latest_path(&self) -> PathBuf {
        self.path.join("latest.json")
    }
    /// `log.csv`.
    pub fn log_path(&self) -> PathBuf {
        self.path.join("log.csv")
    }
    /// `val.csv`.
    pub fn val_path(&self) -> PathBuf {
        self.path.join("val.csv")
    }
    /// `summary.json`.
    pub fn summary_path(&self) -> PathBuf {
        self.path.join("summary.json")
    }
    /// Whether training finished (`summary.json` was written).
    pub fn finished(&self) -> bool {
        self.summary_path().is_file()
    }
    /// Whether a checkpoint was published.
    pub fn has_checkpoint(&self) -> bool {
        self.latest_path().is_file()
    }
    /// Whether a run was started here (`config.json` exists).
    pub fn started(&self) -> bool {
        self.config_path().is_file()
    }

    /// The run's configuration.
    pub fn config(&self) -> crate::Result<TrainConfig> {
        let p = self.config_path();
        let text = read(&p)?;
        let config = TrainConfig::from_json(&text, &p)?;
        config
            .validate()
            .map_err(|e| Error::Config(format!("{}: {e}", p.display())))?;
        Ok(config)
    }

    /// The current checkpoint.
    ///
    /// Its directory must be a checkpoint folder of this run (`ckpt-NNNNNNN`): a `latest.json`
    /// that points anywhere else (`..`, an absolute path) is refused, never followed.
    pub fn latest(&self) -> crate::Result<Latest> {
        let p = self.latest_path();
        let latest: Latest = serde_json::from_str(&read(&p)?)
            .map_err(|e| Error::Checkpoint(format!("{}: {e}", p.display())))?;
        let d = &latest.dir;
        let plain =
            d.len() == 12 && d.starts_with("ckpt-") && d[5..].bytes().all(|b| b.is_ascii_digit());
        if !plain {
            return Err(Error::Checkpoint(format!(
                "{}: names the checkpoint folder {:?}, which is not one of this run's (ckpt-NNNNNNN inside the run); refusing to follow it",
                p.display(),
                mhi_data::sanitize::for_terminal(d)
            )));
        }
        Ok(latest)
    }

    /// The rows of `val.csv` (empty when the file is missing); a malformed row is an error
    /// naming the file, the line and the column.
    pub fn val_rows(&self) -> crate::Result<Vec<ValRow>> {
        let p = self.val_path();
        let Ok(text) = std::fs::read_to_string(&p) else {
            return Ok(Vec::new());
        };
        let mut rows = Vec::new();
        for (i, line) in text.lines().enumerate().skip(1) {
            let f: Vec<&str> = line.split(',').collect();
            let num = |k: usize| -> crate::Result<f64> {
                f.get(k)
                    .and_then(|s| s.trim().parse::<f64>().ok())
                    .filter(|v| v.is_finite())
                    .ok_or_else(|| {
                        Error::Config(format!(
                            "{}:{}: column {} is not a number",
                            p.display(),
                            i + 1,
                            k + 1
                        ))
                    })
            };
            rows.push(ValRow {
                step: num(0)? as usize,
                elapsed_s: num(1)?,
                psnr_learned: num(2)?,
                psnr_soft: num(3)?,
            });
        }
        Ok(rows)
    }
}

fn read(p: &Path) -> crate::Result<String> {
    mhi_data::check_regular_file(p, "run file", 64 << 20).map_err(|e| Error::Data(Box::new(e)))?;
    std::fs::read_to_string(p).map_err(|e| Error::Io {
        path: p.to_path_buf(),
        source: e,
    })
}
