//! Training data from several roots at once, mixed with stated weights, and the validation data
//! that goes with them (a `val` split, or whole sequences held out of training).

use std::path::PathBuf;

use rand::Rng;
use serde::{Deserialize, Serialize};

use crate::dataset::{Dataset, Sequence, root_name};
use crate::error::{Error, Result};
use crate::triplets::{Triplet, TripletSampling, sample_triplet};

/// One root of a training mix, as recorded in a run's `config.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DataSource {
    /// Dataset root in RealEstate10K layout.
    pub root: PathBuf,
    /// Split read for training (`train`).
    pub split: String,
    /// Relative weight: the chance that a step draws from this root is its share of the total.
    pub weight: f64,
    /// Sequences of the split held out of training for validation (plain names, not qualified).
    #[serde(default)]
    pub holdout: Vec<String>,
}

impl DataSource {
    /// A root's `train` split with weight 1 and nothing held out.
    pub fn train(root: impl Into<PathBuf>) -> Self {
        Self {
            root: root.into(),
            split: "train".into(),
            weight: 1.0,
            holdout: Vec::new(),
        }
    }

    /// The folder name that stands for the root in qualified sequence names.
    pub fn name(&self) -> String {
        root_name(&self.root)
    }

    /// Where this root's validation data is: its held-out sequences when there are any, else its
    /// `val` split when the root has one, else nothing.
    pub fn validation(&self) -> Option<(String, Option<Vec<String>>)> {
        if !self.holdout.is_empty() {
            Some((self.split.clone(), Some(self.holdout.clone())))
        } else if self.root.join("val").is_dir() {
            Some(("val".into(), None))
        } else {
            None
        }
    }
}

/// Weighted roots, opened: the training sequences of each (held-out ones removed), or their
/// validation sequences.
#[derive(Debug, Clone)]
pub struct DataMix {
    parts: Vec<(String, Dataset, f64)>,
}

impl DataMix {
    /// Open the training sequences of every source (minus its held-out ones). Each source must
    /// have a positive, finite weight and at least one usable sequence.
    pub fn training(sources: &[DataSource]) -> Result<Self> {
        let mut parts = Vec::new();
        for s in sources {
            check_weight(s)?;
            let ds = Dataset::open(&s.root, &s.split, 3)?.select(&s.holdout, false)?;
            if ds.sequences.is_empty() {
                return Err(Error::Dataset {
                    path: ds.dir,
                    fault: "no training sequence left (each needs 3 frames with images, and held-out sequences are not trained on)".into(),
                });
            }
            parts.push((s.name(), ds, s.weight));
        }
        Self::new(parts)
    }

    /// Open the validation sequences of every source that has some (see
    /// [`DataSource::validation`]); `None` when no source has validation data.
    pub fn validation(sources: &[DataSource]) -> Result<Option<Self>> {
        let mut parts = Vec::new();
        for s in sources {
            check_weight(s)?;
            let Some((split, only)) = s.validation() else {
                continue;
            };
            let ds = Dataset::open(&s.root, &split, 3)?;
            let ds = match only {
                Some(names) => ds.select(&names, true)?,
                None => ds,
            };
            if !ds.sequences.is_empty() {
                parts.push((s.name(), ds, s.weight));
            }
        }
        if parts.is_empty() {
            return Ok(None);
        }
        Self::new(parts).map(Some)
    }

    fn new(parts: Vec<(String, Dataset, f64)>) -> Result<Self> {
        if parts.is_empty() {
            return Err(Error::InvalidArgument("no data source given".into()));
        }
        Ok(Self { parts })
    }

    /// The opened datasets with their names and weights.
    pub fn parts(&self) -> impl Iterator<Item = (&str, &Dataset, f64)> {
        self.parts.iter().map(|(n, d, w)| (n.as_str(), d, *w))
    }

    /// Number of sequences over all roots.
    pub fn sequences(&self) -> usize {
        self.parts.iter().map(|(_, d, _)| d.sequences.len()).sum()
    }

    /// One training triplet: a root drawn by weight, a sequence of it uniformly, a triplet of it
    /// by `sampling`: Stereo Magnification's clips (video or sparse), extrapolation with chance
    /// `extrapolation_share`, or nearest views (the share unused). Tries a few sequences before
    /// giving up with `None`.
    pub fn sample(
        &self,
        sampling: TripletSampling,
        extrapolation_share: f64,
        rng: &mut impl Rng,
    ) -> Option<(&Sequence, Triplet)> {
        let total: f64 = self.parts.iter().map(|p| p.2).sum();
        for _ in 0..32 {
            let mut x = rng.random::<f64>() * total;
            let mut pick = &self.parts[self.parts.len() - 1].1;
            for (_, d, w) in &self.parts {
                if x < *w {
                    pick = d;
                    break;
                }
                x -= w;
            }
            let seq = &pick.sequences[rng.random_range(0..pick.sequences.len())];
            if let Some(t) = sample_triplet(seq, sampling, extrapolation_share, rng) {
                return Some((seq, t));
            }
        }
        None
    }
}

fn check_weight(s: &DataSource) -> Result<()> {
    if s.weight.is_finite() && s.weight > 0.0 {
        Ok(())
    } else {
        Err(Error::InvalidArgument(format!(
            "the weight of {} is {}; it must be a positive number",
            s.root.display(),
            s.weight
        )))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{SynthConfig, generate};
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn a_stretch_of_a_sequence_is_held_out_and_training_never_spans_it() {
        let dir = tempfile::tempdir().unwrap();
        let c = SynthConfig {
            scenes: 1,
            frames: 10,
            width: 16,
            height: 12,
            seed: 3,
            test_fraction: 0.0,
            val_fraction: 0.0,
            ..SynthConfig::default()
        };
        generate(&c, dir.path(), &|| {}).unwrap();
        let ds = || Dataset::open(dir.path(), "train", 3).unwrap();
        let seq = ds().sequences[0].clone();
        let shape = |d: &Dataset| -> Vec<(String, usize)> {
            d.sequences
                .iter()
                .map(|s| (s.name.clone(), s.frames.len()))
                .collect()
        };
        let name = &seq.name;
        // The tail to validation, the rest to training.
        let tail = vec![format!("{name}@6..")];
        assert_eq!(
            shape(&ds().select(&tail, true).unwrap()),
            [(format!("{name}@6..10"), 4)]
        );
        assert_eq!(
            shape(&ds().select(&tail, false).unwrap()),
            [(format!("{name}@0..6"), 6)]
        );
        // A stretch from the middle leaves two training pieces, so no triplet spans it.
        let mid = vec![format!("{name}@3..6")];
        assert_eq!(
            shape(&ds().select(&mid, false).unwrap()),
            [(format!("{name}@0..3"), 3), (format!("{name}@6..10"), 4)]
        );
        let kept = ds().select(&mid, true).unwrap();
        assert_eq!(kept.sequences[0].frames, seq.frames[3..6]);
        // Through a source, as `train --holdout ROOT/SEQ@FROM..` gives it.
        let source = DataSource {
            holdout: tail.clone(),
            ..DataSource::train(dir.path())
        };
        let train = DataMix::training(std::slice::from_ref(&source)).unwrap();
        let val = DataMix::validation(&[source]).unwrap().unwrap();
        assert_eq!(train.sequences() + val.sequences(), 2);
        // Stretches that are not one.
        for bad in ["@6..6", "@8..3", "@0..11", "@x..", "@3", "@..4"] {
            let e = ds().select(&[format!("{name}{bad}")], true).unwrap_err();
            assert!(e.to_string().contains("stretch"), "{bad}: {e}");
        }
    }

    #[test]
    fn mix_draws_by_weight_and_keeps_holdouts_out() {
        let a = tempfile::tempdir().unwrap();
        let b = tempfile::tempdir().unwrap();
        for (dir, seed) in [(&a, 1), (&b, 2)] {
            let c = SynthConfig {
                scenes: 5,
                frames: 4,
                width: 16,
                height: 12,
                seed,
                ..SynthConfig::default()
            };
            generate(&c, dir.path(), &|| {}).unwrap();
        }
        let held = Dataset::open(a.path(), "train", 3).unwrap().sequences[0]
            .name
            .clone();
        let sources = [
            DataSource {
                holdout: vec![held.clone()],
                weight: 3.0,
                ..DataSource::train(a.path())
            },
            DataSource::train(b.path()),
        ];
        let mix = DataMix::training(&sources).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(0);
        let mut from_a = 0;
        for _ in 0..400 {
            let (seq, _) = mix.sample(TripletSampling::Clips, 0.5, &mut rng).unwrap();
            assert_ne!(
                seq.camera_file,
                a.path().join("train").join(format!("{held}.txt"))
            );
            if seq.camera_file.starts_with(a.path()) {
                from_a += 1;
            }
        }
        // Weight 3 : 1 → about 300 of 400.
        assert!((260..340).contains(&from_a), "{from_a}");
        let val = DataMix::validation(&sources).unwrap().unwrap();
        let names: Vec<_> = val
            .parts()
            .flat_map(|(_, d, _)| d.sequences.iter().map(|s| s.name.clone()))
            .collect();
        // Root a: its held-out sequence (a holdout takes precedence over its val split); root b
        // has no holdout, so its `val` split (scene 3 of 5: 3 train, 1 val, 1 test).
        assert_eq!(names, vec![held, "scene_00003".to_string()]);
        // A typo in a held-out name is an error naming the sequences there are.
        let bad = [DataSource {
            holdout: vec!["nope".into()],
            ..DataSource::train(a.path())
        }];
        let e = DataMix::training(&bad).unwrap_err().to_string();
        assert!(e.contains("nope") && e.contains("sequences are"), "{e}");
        let zero = [DataSource {
            weight: 0.0,
            ..DataSource::train(a.path())
        }];
        assert!(DataMix::training(&zero).is_err());
    }
}
