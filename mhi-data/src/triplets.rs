//! Triplets (reference, source, target) drawn from posed clips, binned by rotation.

use std::path::Path;

use mhi_geom::RigidTransform;
use rand::Rng;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::dataset::{Dataset, Sampling, Sequence};
use crate::error::{Error, Result};

/// Frames per training clip (Stereo Magnification).
pub const CLIP_LEN: usize = 10;
/// Range of the random stride between clip frames (Stereo Magnification).
pub const STRIDE_RANGE: std::ops::RangeInclusive<usize> = 3..=10;
/// Views per clip of a sparse capture: triplets come from neighbouring views.
pub const SPARSE_CLIP_LEN: usize = 5;

/// Whether the target lies between the two input views in time or beyond them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum TripletKind {
    /// The target is between the reference and the source.
    Interpolation,
    /// The target is outside the span of the reference and the source.
    Extrapolation,
}

/// Rotation bins of the evaluation (largest relative rotation angle in the triplet).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum RotationBin {
    /// θ ≤ 2°.
    #[serde(rename = "0-2")]
    UpTo2,
    /// 2° < θ ≤ 4°.
    #[serde(rename = "2-4")]
    From2To4,
    /// 4° < θ ≤ 8°.
    #[serde(rename = "4-8")]
    From4To8,
    /// θ > 8°.
    #[serde(rename = ">8")]
    Over8,
}

impl RotationBin {
    /// All bins, in increasing order.
    pub const ALL: [Self; 4] = [Self::UpTo2, Self::From2To4, Self::From4To8, Self::Over8];

    /// The bin of an angle in degrees.
    pub fn of(deg: f64) -> Self {
        if deg <= 2.0 {
            Self::UpTo2
        } else if deg <= 4.0 {
            Self::From2To4
        } else if deg <= 8.0 {
            Self::From4To8
        } else {
            Self::Over8
        }
    }

    /// The bin's key in reports and JSON (its serde name), e.g. `"2-4"`.
    pub const fn key(self) -> &'static str {
        match self {
            Self::UpTo2 => "0-2",
            Self::From2To4 => "2-4",
            Self::From4To8 => "4-8",
            Self::Over8 => ">8",
        }
    }

    /// The bin of a report key ([`Self::key`]).
    pub fn from_key(key: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|b| b.key() == key)
    }

    /// Short label for tables, e.g. `"2-4°"`.
    pub fn label(self) -> &'static str {
        match self {
            Self::UpTo2 => "≤2°",
            Self::From2To4 => "2-4°",
            Self::From4To8 => "4-8°",
            Self::Over8 => ">8°",
        }
    }
}

/// A reference view, a source view and a target view of one sequence.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Triplet {
    /// Sequence name.
    pub sequence: String,
    /// Index of the reference frame in the sequence's frames (the MHI is built on its grid).
    pub reference: usize,
    /// Index of the second input frame.
    pub source: usize,
    /// Index of the frame to synthesise.
    pub target: usize,
    /// Interpolation or extrapolation.
    pub kind: TripletKind,
    /// Largest pairwise relative rotation angle among the three views, in degrees.
    pub max_rotation_deg: f64,
    /// The bin of `max_rotation_deg`.
    pub bin: RotationBin,
    /// Timestamps of the reference, source and target frames, so that an index reused after
    /// frames were added or deleted is caught rather than scored against other frames (absent
    /// in indices written before they were recorded).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub timestamps: Option<[u64; 3]>,
}

/// Largest pairwise relative rotation angle of three poses, in degrees.
pub fn max_rotation_deg(poses: [&RigidTransform; 3]) -> f64 {
    let pair = |a: &RigidTransform, b: &RigidTransform| {
        RigidTransform::relative(a, b).rotation_angle_deg()
    };
    pair(poses[0], poses[1])
        .max(pair(poses[0], poses[2]))
        .max(pair(poses[1], poses[2]))
}

fn make(
    seq: &Sequence,
    reference: usize,
    source: usize,
    target: usize,
    kind: TripletKind,
) -> Triplet {
    let pose = |i: usize| &seq.frames[i].row.cam_from_world;
    let max_rotation_deg = max_rotation_deg([pose(reference), pose(source), pose(target)]);
    let ts = |i: usize| seq.frames[i].row.timestamp;
    Triplet {
        timestamps: Some([ts(reference), ts(source), ts(target)]),
        sequence: seq.name.clone(),
        reference,
        source,
        target,
        kind,
        max_rotation_deg,
        bin: RotationBin::of(max_rotation_deg),
    }
}

/// A clip of frame indices: up to [`CLIP_LEN`] frames at a random stride in [`STRIDE_RANGE`],
/// shrunk to fit short sequences (shorter stride first, then fewer frames), randomly reversed.
pub fn sample_clip(n_frames: usize, rng: &mut impl Rng) -> Vec<usize> {
    if n_frames == 0 {
        return Vec::new();
    }
    let len = CLIP_LEN.min(n_frames);
    let max_stride = if len > 1 {
        (n_frames - 1) / (len - 1)
    } else {
        1
    };
    let stride = rng.random_range(STRIDE_RANGE).min(max_stride.max(1));
    let span = (len - 1) * stride;
    let start = rng.random_range(0..=(n_frames - 1 - span));
    let mut clip: Vec<usize> = (0..len).map(|k| start + k * stride).collect();
    if rng.random_bool(0.5) {
        clip.reverse();
    }
    clip
}

/// A clip of `seq` drawn by its [`Sampling`]: Stereo Magnification's clip for video, up to
/// [`SPARSE_CLIP_LEN`] consecutive views (randomly reversed) for a sparse capture.
pub fn sample_clip_for(seq: &Sequence, rng: &mut impl Rng) -> Vec<usize> {
    let n = seq.frames.len();
    match seq.sampling() {
        Sampling::Video => sample_clip(n, rng),
        Sampling::Sparse => {
            if n == 0 {
                return Vec::new();
            }
            let len = SPARSE_CLIP_LEN.min(n);
            let start = rng.random_range(0..=n - len);
            let mut clip: Vec<usize> = (start..start + len).collect();
            if rng.random_bool(0.5) {
                clip.reverse();
            }
            clip
        }
    }
}

/// Pick (reference, source, target) positions in a clip of `len` frames for the given kind, or
/// `None` when the clip is too short (interpolation needs 3 frames, extrapolation 3 too).
fn pick(len: usize, kind: TripletKind, rng: &mut impl Rng) -> Option<(usize, usize, usize)> {
    if len < 3 {
        return None;
    }
    let (a, b, t) = match kind {
        TripletKind::Interpolation => {
            let a = rng.random_range(0..len - 2);
            let b = rng.random_range(a + 2..len);
            let t = rng.random_range(a + 1..b);
            (a, b, t)
        }
        TripletKind::Extrapolation => {
            // Target at one end, both inputs on the same side of it.
            let t_at_end = rng.random_bool(0.5);
            let (lo, hi) = if t_at_end { (0, len - 1) } else { (1, len) };
            let a = rng.random_range(lo..hi - 1);
            let b = rng.random_range(a + 1..hi);
            let t = if t_at_end {
                rng.random_range(b + 1..len)
            } else {
                rng.random_range(0..a.max(1))
            };
            (a, b, t)
        }
    };
    // Either input may be the reference.
    Some(if rng.random_bool(0.5) {
        (a, b, t)
    } else {
        (b, a, t)
    })
}

/// Stereo Magnification's chance that a training triplet is an extrapolation: half and half.
/// The default of a run's `extrapolation_share`, and the draw of every validation sample.
pub const PAPER_EXTRAPOLATION_SHARE: f64 = 0.5;

/// One training triplet in Stereo Magnification's scheme; `kind` is extrapolation with chance
/// `extrapolation_share` (Stereo Magnification: 0.5) and interpolation otherwise. A share outside
/// [0, 1] or NaN is taken as 0.5 (callers validate it where the user gives it).
pub fn sample_training_triplet(
    seq: &Sequence,
    extrapolation_share: f64,
    rng: &mut impl Rng,
) -> Option<Triplet> {
    let clip = sample_clip_for(seq, rng);
    let share = if (0.0..=1.0).contains(&extrapolation_share) {
        extrapolation_share
    } else {
        PAPER_EXTRAPOLATION_SHARE
    };
    // Drawn as "interpolation with chance 1 − share" so that share 0.5 draws exactly the
    // triplets of runs written before the share existed (resumes stay bit-identical).
    let kind = if rng.random_bool(1.0 - share) {
        TripletKind::Interpolation
    } else {
        TripletKind::Extrapolation
    };
    let (r, s, t) = pick(clip.len(), kind, rng)?;
    Some(make(seq, clip[r], clip[s], clip[t], kind))
}

/// How training triplets are drawn from a sequence.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum TripletSampling {
    /// Stereo Magnification's clips ([`sample_training_triplet`]): frames at a random stride
    /// for video, [`SPARSE_CLIP_LEN`] consecutive views for a sparse capture; the kind drawn
    /// with the run's extrapolation share.
    #[default]
    Clips,
    /// Nearest views by camera centre ([`sample_neighbour_triplet`]): a random reference, the
    /// source among its [`NEIGHBOUR_SOURCES`] nearest views, the target among its
    /// [`NEIGHBOUR_TARGETS`] nearest other than the source; the kind follows from where the
    /// target lies. Small baselines whatever the order of the views.
    Neighbours,
    /// By the capture ([`crate::Sequence::sampling`]): clips for video, whose consecutive
    /// frames are near views already, and nearest views for a sparse capture, whose
    /// consecutive views may lie far apart.
    ByCapture,
}

/// One training triplet of `seq` drawn by `sampling` (`extrapolation_share` applies to clips
/// only); `None` when the sequence is too short.
pub fn sample_triplet(
    seq: &Sequence,
    sampling: TripletSampling,
    extrapolation_share: f64,
    rng: &mut impl Rng,
) -> Option<Triplet> {
    let neighbours = match sampling {
        TripletSampling::Clips => false,
        TripletSampling::Neighbours => true,
        TripletSampling::ByCapture => seq.sampling() == crate::Sampling::Sparse,
    };
    if neighbours {
        sample_neighbour_triplet(seq, rng)
    } else {
        sample_training_triplet(seq, extrapolation_share, rng)
    }
}

/// How many of the reference's nearest views a neighbour triplet's source is drawn from.
pub const NEIGHBOUR_SOURCES: usize = 3;
/// How many of the reference's nearest views a neighbour triplet's target is drawn from (the
/// source excluded).
pub const NEIGHBOUR_TARGETS: usize = 4;

/// One training triplet of nearest views (see [`TripletSampling::Neighbours`]): the reference
/// uniformly, the source uniformly among its [`NEIGHBOUR_SOURCES`] nearest views by camera
/// centre, the target uniformly among its [`NEIGHBOUR_TARGETS`] nearest other than the source.
/// An interpolation when the target's centre projects strictly inside the segment from the
/// reference's centre to the source's, else an extrapolation. `None` for fewer than 3 frames
/// or when the views' centres are not finite. Ties in distance go to the lower frame index.
pub fn sample_neighbour_triplet(seq: &Sequence, rng: &mut impl Rng) -> Option<Triplet> {
    let n = seq.frames.len();
    if n < 3 {
        return None;
    }
    let centre = |i: usize| seq.frames[i].row.cam_from_world.center();
    if (0..n).any(|i| !centre(i).is_finite()) {
        return None;
    }
    let r = rng.random_range(0..n);
    let cr = centre(r);
    let mut near: Vec<usize> = (0..n).filter(|&i| i != r).collect();
    near.sort_by(|a, b| {
        centre(*a)
            .distance_squared(cr)
            .total_cmp(&centre(*b).distance_squared(cr))
            .then(a.cmp(b))
    });
    let s = near[rng.random_range(0..NEIGHBOUR_SOURCES.min(near.len()))];
    let targets: Vec<usize> = near[..NEIGHBOUR_TARGETS.min(near.len())]
        .iter()
        .copied()
        .filter(|&i| i != s)
        .collect();
    let t = targets[rng.random_range(0..targets.len())];
    let (cs, ct) = (centre(s), centre(t));
    let base = cs - cr;
    let along = if base.length_squared() > 0.0 {
        (ct - cr).dot(base) / base.length_squared()
    } else {
        f64::NAN
    };
    let kind = if along > 0.0 && along < 1.0 {
        TripletKind::Interpolation
    } else {
        TripletKind::Extrapolation
    };
    Some(make(seq, r, s, t, kind))
}

/// A saved, reproducible set of evaluation triplets.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TripletIndex {
    /// The seed the triplets were drawn with.
    pub seed: u64,
    /// The triplets, half interpolation and half extrapolation.
    pub triplets: Vec<Triplet>,
    /// Sequences that could not supply the distinct triplets asked of them, with how many they
    /// gave (not saved: a warning for whoever drew the index).
    #[serde(skip)]
    pub shortfalls: Vec<(String, usize)>,
}

impl TripletIndex {
    /// Draw `per_sequence` triplets from every sequence, deterministically for `seed`, alternating
    /// interpolation and extrapolation so that each is half of the total (±1).
    ///
    /// Every triplet of a sequence is distinct: a draw that repeats one is drawn again (the
    /// draws are those of an index without repeats otherwise), and a sequence too short to
    /// supply `per_sequence` distinct triplets gives what it has and is listed in
    /// [`TripletIndex::shortfalls`] — repeated triplets would make the bootstrap intervals
    /// too narrow.
    pub fn sample(dataset: &Dataset, per_sequence: usize, seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut triplets = Vec::new();
        let mut shortfalls = Vec::new();
        let mut k = 0usize;
        for seq in &dataset.sequences {
            let mut seen = std::collections::HashSet::new();
            let (mut attempts, mut extra, max_extra) = (per_sequence, 0, 20 * per_sequence + 100);
            let mut repeated = false;
            let mut i = 0;
            while i < attempts {
                i += 1;
                let kind = if k.is_multiple_of(2) {
                    TripletKind::Interpolation
                } else {
                    TripletKind::Extrapolation
                };
                let clip = sample_clip_for(seq, &mut rng);
                if let Some((r, s, t)) = pick(clip.len(), kind, &mut rng) {
                    if seen.insert((clip[r], clip[s], clip[t])) {
                        triplets.push(make(seq, clip[r], clip[s], clip[t], kind));
                        k += 1;
                    } else {
                        repeated = true;
                        if extra < max_extra {
                            extra += 1;
                            attempts += 1;
                        }
                    }
                }
            }
            if repeated && seen.len() < per_sequence {
                shortfalls.push((seq.name.clone(), seen.len()));
            }
        }
        Self {
            seed,
            triplets,
            shortfalls,
        }
    }

    /// Write as pretty JSON, atomically.
    pub fn save(&self, path: &Path) -> Result<()> {
        let text = serde_json::to_vec_pretty(self).map_err(|source| Error::Json {
            path: path.to_path_buf(),
            source,
        })?;
        crate::write_atomic(path, &text)
    }

    /// Read from JSON.
    pub fn load(path: &Path) -> Result<Self> {
        let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
        serde_json::from_slice(&bytes).map_err(|source| Error::Json {
            path: path.to_path_buf(),
            source,
        })
    }

    /// Check that every triplet refers to a sequence and frames of `dataset`.
    pub fn validate(&self, dataset: &Dataset, index_path: &Path) -> Result<()> {
        for (i, t) in self.triplets.iter().enumerate() {
            let seq = dataset.sequence(&t.sequence);
            let ok = seq.is_some_and(|s| {
                let n = s.frames.len();
                t.reference < n && t.source < n && t.target < n
            });
            if ok && (t.reference == t.source || t.target == t.reference || t.target == t.source) {
                return Err(Error::Dataset {
                    path: index_path.to_path_buf(),
                    fault: format!(
                        "triplet {i} of sequence {:?} uses one frame twice (reference {}, source {}, target {}): a view synthesised from itself says nothing",
                        t.sequence, t.reference, t.source, t.target
                    ),
                });
            }
            if let (true, Some(ts), Some(s)) = (ok, t.timestamps, seq) {
                let now = [t.reference, t.source, t.target].map(|k| s.frames[k].row.timestamp);
                if now != ts {
                    return Err(Error::Dataset {
                        path: index_path.to_path_buf(),
                        fault: format!(
                            "triplet {i} of sequence {:?} was drawn for frames with timestamps {ts:?}, but frames ({}, {}, {}) of {} now have {now:?}: frames were added or deleted since the index was made; draw a new index",
                            t.sequence,
                            t.reference,
                            t.source,
                            t.target,
                            dataset.dir.display()
                        ),
                    });
                }
            }
            if !ok {
                return Err(Error::Dataset {
                    path: index_path.to_path_buf(),
                    fault: format!(
                        "triplet {i} refers to sequence {:?} frames ({}, {}, {}), which {} does not have",
                        t.sequence,
                        t.reference,
                        t.source,
                        t.target,
                        dataset.dir.display()
                    ),
                });
            }
        }
        Ok(())
    }

    /// Count of triplets per rotation bin, in bin order.
    pub fn bin_counts(&self) -> [usize; 4] {
        let mut c = [0; 4];
        for t in &self.triplets {
            c[t.bin as usize] += 1;
        }
        c
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dataset::Frame;
    use crate::re10k::CameraRow;
    use glam::{DMat3, DVec3};

    fn seq(n: usize, deg_per_frame: f64) -> Sequence {
        Sequence {
            name: "s".into(),
            camera_file: "s.txt".into(),
            frames: (0..n)
                .map(|i| Frame {
                    row: CameraRow {
                        timestamp: i as u64,
                        intrinsics: [0.5, 0.5, 0.5, 0.5],
                        distortion: [0.0; 2],
                        cam_from_world: RigidTransform::new(
                            DMat3::from_rotation_y((i as f64 * deg_per_frame).to_radians()),
                            DVec3::new(i as f64 * 0.1, 0.0, 0.0),
                        )
                        .unwrap(),
                    },
                    path: format!("{i}.png").into(),
                })
                .collect(),
        }
    }

    /// Neighbour triplets follow the cameras, not the frame order: on views along a line
    /// stored in a scrambled order, the source is among the reference's 3 nearest, the target
    /// among its 4 nearest other than the source, the kind is where the target lies, and both
    /// kinds occur; a draw is deterministic for its seed.
    #[test]
    fn neighbour_triplets_are_the_nearest_views() {
        let order = [7_usize, 2, 9, 0, 5, 11, 3, 8, 1, 10, 4, 6];
        let mut s = seq(order.len(), 0.0);
        for (f, &pos) in s.frames.iter_mut().zip(&order) {
            f.row.cam_from_world =
                RigidTransform::new(DMat3::IDENTITY, DVec3::new(pos as f64, 0.0, 0.0)).unwrap();
        }
        let x = |i: usize| s.frames[i].row.cam_from_world.center().x;
        let rank = |r: usize, i: usize| {
            // How many views are nearer to r than i (integer positions: exact distances;
            // ties go to the lower index, as in the sampler).
            (0..order.len())
                .filter(|&k| k != r && k != i)
                .filter(|&k| {
                    let (dk, di) = ((x(k) - x(r)).abs(), (x(i) - x(r)).abs());
                    dk < di || (dk == di && k < i)
                })
                .count()
        };
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let mut kinds = std::collections::HashSet::new();
        for _ in 0..500 {
            let t = sample_neighbour_triplet(&s, &mut rng).unwrap();
            assert!(rank(t.reference, t.source) < NEIGHBOUR_SOURCES, "{t:?}");
            let target_rank = rank(t.reference, t.target);
            let below = usize::from(rank(t.reference, t.source) < target_rank);
            assert!(target_rank < NEIGHBOUR_TARGETS, "{t:?}");
            assert!(target_rank - below < NEIGHBOUR_TARGETS, "{t:?}");
            assert_ne!(t.source, t.target);
            assert_ne!(t.reference, t.target);
            let (r, so, ta) = (x(t.reference), x(t.source), x(t.target));
            let between = (ta - r) * (so - r) > 0.0 && (ta - r).abs() < (so - r).abs();
            let want = if between {
                TripletKind::Interpolation
            } else {
                TripletKind::Extrapolation
            };
            assert_eq!(t.kind, want, "{t:?}");
            kinds.insert(t.kind);
        }
        assert_eq!(kinds.len(), 2);
        let draw = |seed| sample_neighbour_triplet(&s, &mut ChaCha8Rng::seed_from_u64(seed));
        assert_eq!(draw(9), draw(9));
        assert!(sample_neighbour_triplet(&seq(2, 0.0), &mut rng).is_none());
    }

    /// By capture, a sparse capture draws nearest views and video draws clips: the same
    /// triplets as those samplers for the same seed.
    #[test]
    fn triplets_by_capture_follow_the_capture() {
        let sparse = seq(12, 0.0);
        let mut video = seq(40, 0.0);
        for (i, f) in video.frames.iter_mut().enumerate() {
            f.row.timestamp = i as u64 * 33_333;
        }
        assert_eq!(sparse.sampling(), crate::Sampling::Sparse);
        assert_eq!(video.sampling(), crate::Sampling::Video);
        let rng = |seed| ChaCha8Rng::seed_from_u64(seed);
        for seed in 0..50 {
            let by =
                |s: &Sequence| sample_triplet(s, TripletSampling::ByCapture, 0.7, &mut rng(seed));
            assert_eq!(
                by(&sparse),
                sample_neighbour_triplet(&sparse, &mut rng(seed))
            );
            assert_eq!(
                by(&video),
                sample_training_triplet(&video, 0.7, &mut rng(seed))
            );
        }
        // The two samplers differ on the sparse capture (else the test above could not fail).
        assert!((0..50).any(|seed| {
            sample_neighbour_triplet(&sparse, &mut rng(seed))
                != sample_training_triplet(&sparse, 0.7, &mut rng(seed))
        }));
    }

    #[test]
    fn bins() {
        assert_eq!(RotationBin::of(0.0), RotationBin::UpTo2);
        assert_eq!(RotationBin::of(2.0), RotationBin::UpTo2);
        assert_eq!(RotationBin::of(2.0001), RotationBin::From2To4);
        assert_eq!(RotationBin::of(8.0), RotationBin::From4To8);
        assert_eq!(RotationBin::of(30.0), RotationBin::Over8);
        // One vocabulary: the report key is the serde name, and it maps back.
        for b in RotationBin::ALL {
            assert_eq!(serde_json::to_value(b).unwrap(), b.key());
            assert_eq!(RotationBin::from_key(b.key()), Some(b));
        }
    }

    #[test]
    fn clips_respect_stride_and_length() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        for n in [1usize, 3, 8, 10, 40, 200] {
            for _ in 0..200 {
                let c = sample_clip(n, &mut rng);
                assert_eq!(c.len(), CLIP_LEN.min(n));
                assert!(c.iter().all(|&i| i < n));
                if c.len() > 1 {
                    let stride = c[0].abs_diff(c[1]);
                    assert!(c.windows(2).all(|w| w[0].abs_diff(w[1]) == stride));
                    if n >= 91 {
                        assert!(STRIDE_RANGE.contains(&stride), "{stride}");
                    }
                }
            }
        }
    }

    #[test]
    fn training_triplets_are_half_interpolation_and_correct() {
        let s = seq(100, 0.5);
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let mut interp = 0;
        for _ in 0..2000 {
            let t = sample_training_triplet(&s, 0.5, &mut rng).unwrap();
            let (lo, hi) = (t.reference.min(t.source), t.reference.max(t.source));
            assert!(t.reference != t.source && t.target != t.reference && t.target != t.source);
            match t.kind {
                TripletKind::Interpolation => {
                    interp += 1;
                    assert!(lo < t.target && t.target < hi);
                }
                TripletKind::Extrapolation => assert!(t.target < lo || t.target > hi),
            }
            // Rotation is about one axis at 0.5°/frame: the largest angle is the widest span.
            let span = [t.reference, t.source, t.target];
            let width = span.iter().max().unwrap() - span.iter().min().unwrap();
            assert!((t.max_rotation_deg - width as f64 * 0.5).abs() < 1e-9);
        }
        assert!((900..1100).contains(&interp), "{interp}");
    }

    #[test]
    fn the_extrapolation_share_sets_the_mix_and_half_is_the_old_draw() {
        let s = seq(100, 0.5);
        let count = |share: f64| {
            let mut rng = ChaCha8Rng::seed_from_u64(9);
            (0..2000)
                .filter(|_| {
                    sample_training_triplet(&s, share, &mut rng).unwrap().kind
                        == TripletKind::Extrapolation
                })
                .count()
        };
        assert!((1400..1600).contains(&count(0.75)), "{}", count(0.75));
        assert_eq!(count(1.0), 2000);
        assert_eq!(count(0.0), 0);
        // Out of range: the paper's 50/50.
        assert!((900..1100).contains(&count(f64::NAN)));
        // Share 0.5 consumes the generator as the unparameterised draw did (bool at p = 0.5,
        // then the clip and the frames), so resumed runs draw the same triplets.
        let mut a = ChaCha8Rng::seed_from_u64(3);
        let mut b = ChaCha8Rng::seed_from_u64(3);
        for _ in 0..50 {
            let t = sample_training_triplet(&s, 0.5, &mut a).unwrap();
            let clip = sample_clip_for(&s, &mut b);
            let kind = if b.random_bool(0.5) {
                TripletKind::Interpolation
            } else {
                TripletKind::Extrapolation
            };
            let (r, src, tg) = pick(clip.len(), kind, &mut b).unwrap();
            assert_eq!(
                (t.reference, t.source, t.target, t.kind),
                (clip[r], clip[src], clip[tg], kind)
            );
        }
    }

    #[test]
    fn eval_index_is_deterministic_balanced_and_round_trips() {
        let ds = Dataset {
            dir: "d".into(),
            sequences: vec![seq(30, 1.0), {
                let mut s = seq(12, 0.2);
                s.name = "t".into();
                s
            }],
            warnings: vec![],
            skipped_sequences: 0,
            missing_frames: 0,
        };
        let a = TripletIndex::sample(&ds, 10, 42);
        let b = TripletIndex::sample(&ds, 10, 42);
        assert_eq!(a, b);
        assert_ne!(a, TripletIndex::sample(&ds, 10, 43));
        let interp = a
            .triplets
            .iter()
            .filter(|t| t.kind == TripletKind::Interpolation)
            .count();
        assert_eq!(a.triplets.len(), 20);
        assert_eq!(interp, 10);
        assert_eq!(a.bin_counts().iter().sum::<usize>(), 20);
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("index.json");
        a.save(&p).unwrap();
        assert_eq!(TripletIndex::load(&p).unwrap(), a);
        a.validate(&ds, &p).unwrap();
        let mut bad = a.clone();
        bad.triplets[0].target = 99;
        let err = bad.validate(&ds, &p).unwrap_err().to_string();
        assert!(
            err.contains("index.json") && err.contains("triplet 0"),
            "{err}"
        );
        std::fs::write(&p, "{ not json").unwrap();
        assert!(matches!(TripletIndex::load(&p), Err(Error::Json { .. })));
    }
}
