//! Scene analysis before rendering: what an MHI does not need for a given set of target views,
//! decided with the same error budget as the render ([`Prune`]) and recorded so a user can see
//! what was left out, why, and the bound it kept.

use mhi_geom::Camera;
use serde::{Deserialize, Serialize};

use crate::cpu::{Prune, layers_to_skip, normals_to_drop};
use crate::error::{Error, Result};
use crate::mhi::{LayerColor, Mhi};

/// How one normal is used by the target views.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NormalUse {
    /// Index in the MHI's normal set.
    pub index: usize,
    /// The normal (reference camera frame).
    pub normal: [f64; 3],
    /// Its largest blend weight over every pixel of every target view.
    pub max_weight: f32,
    /// Left out of every view: its weight fits the budget's normal share everywhere.
    pub dropped: bool,
    /// Layers of this normal with no alpha at all (the farthest excepted).
    pub layers_empty: usize,
    /// Layers of this normal left out within the budget's layer share (the empty ones
    /// included).
    pub layers_skipped: usize,
    /// Their summed largest alpha: the most they could change a pixel of this normal's image.
    pub skipped_mass: f32,
    /// Nearest and farthest depth of the layers kept besides the farthest (the occupied depth
    /// range), `None` when only the farthest is kept.
    pub occupied_depths: Option<[f64; 2]>,
    /// The depth indices kept (far first; empty when the normal is dropped).
    pub kept_depths: Vec<usize>,
    /// Why, in words.
    pub reason: String,
}

/// What an MHI needs for a set of views, within one budget.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ScenePlan {
    /// The budget (colour units per pixel).
    pub budget: f32,
    /// Target views analysed.
    pub views: usize,
    /// Normals N and planes D.
    pub normals: usize,
    /// Planes per normal.
    pub planes: usize,
    /// Per normal.
    pub per_normal: Vec<NormalUse>,
    /// Layers (N · D) kept: those of kept normals that are not skipped.
    pub layers_kept: usize,
    /// Reference pixels where every layer of every kept normal in front of the farthest is
    /// transparent beyond the layer share (nothing but the far plane there).
    pub background_fraction: f64,
    /// Bytes of the MHI's layers (alpha f32 per texel, plus colour: shared once, or RGB per
    /// layer) with everything, and with only what is kept.
    pub bytes_exact: usize,
    /// See [`ScenePlan::bytes_exact`].
    pub bytes_kept: usize,
    /// The largest change any pixel of any analysed view can see from what this plan leaves out
    /// (worst normal's skipped mass + worst pixel's dropped weight + the transmittance stop).
    pub bound: f32,
}

impl ScenePlan {
    /// Whether layer `(normal, depth)` is kept.
    pub fn keeps(&self, normal: usize, depth: usize) -> bool {
        self.per_normal
            .get(normal)
            .is_some_and(|u| u.kept_depths.contains(&depth))
    }

    /// The plan as lines of text (what `render --explain` prints).
    pub fn explain(&self) -> String {
        let mut s = format!(
            "scene plan for {} view(s), budget {:.5} per pixel ({:.2} of an 8-bit level); guaranteed bound {:.5}\n",
            self.views,
            self.budget,
            self.budget * 255.0,
            self.bound
        );
        for u in &self.per_normal {
            s += &format!(
                "  normal {} ({:+.2}, {:+.2}, {:+.2}): {}\n",
                u.index, u.normal[0], u.normal[1], u.normal[2], u.reason
            );
        }
        s += &format!(
            "  layers kept {} of {}; background only (far plane) at {:.1} % of reference pixels\n  size of the layers {:.2} MB exact, {:.2} MB kept ({:.0} %)",
            self.layers_kept,
            self.normals * self.planes,
            100.0 * self.background_fraction,
            self.bytes_exact as f64 / 1e6,
            self.bytes_kept as f64 / 1e6,
            100.0 * self.bytes_kept as f64 / self.bytes_exact.max(1) as f64
        );
        s
    }
}

/// Decide what `mhi` does not need to render `targets`, each with its blend weights
/// (`N × H × W`, normalised; e.g. [`crate::heuristic_weights`]), within `prune`'s budget: the
/// same rules as [`crate::render`], applied to all views at once (a normal is dropped only if
/// every view may drop it; layers are skipped whatever their visibility).
///
/// # Errors
/// When a view's weights do not have `N × H × W` entries.
pub fn analyse(mhi: &Mhi, targets: &[(&Camera, &[f32])], prune: Prune) -> Result<ScenePlan> {
    let mut views = ViewsSeen::new(mhi, prune);
    for (cam, w) in targets {
        views.add(cam, w)?;
    }
    views.finish(mhi)
}

/// The least clearance a camera path keeps from every plane of an MHI that holds something, as
/// a fraction of the plane's own distance from the reference camera.
pub const MIN_PATH_CLEARANCE: f64 = 0.05;

/// A plane "holds something" when it carries at least this share of its normal's composite in
/// the reference view (its alpha times the transmittance of the planes in front, averaged over
/// the pixels): below it, what a camera behind the plane loses is a speck, not an object.
pub const MIN_PLANE_SHARE: f64 = 0.01;

/// Each layer's share of its normal's composite in the reference view (`N × D`, normal-major):
/// `mean over pixels of α_j Π_{k nearer} (1 − α_k)`.
pub fn reference_shares(mhi: &Mhi) -> Vec<f64> {
    let (n, d) = (mhi.n(), mhi.d());
    let px = mhi.reference().width as usize * mhi.reference().height as usize;
    let mut shares = vec![0.0; n * d];
    // Depths are far first: composite from the last (nearest) layer back.
    let near_first: Vec<usize> = {
        let mut v: Vec<usize> = (0..d).collect();
        v.sort_by(|a, b| mhi.depths()[*a].total_cmp(&mhi.depths()[*b]));
        v
    };
    for i in 0..n {
        let mut transmittance = vec![1.0_f64; px];
        for &j in &near_first {
            let mut sum = 0.0;
            for (t, &a) in transmittance.iter_mut().zip(mhi.alpha_layer(i, j)) {
                let a = f64::from(a.clamp(0.0, 1.0));
                sum += a * *t;
                *t *= 1.0 - a;
            }
            shares[i * d + j] = sum / px as f64;
        }
    }
    shares
}

/// How close a camera path comes to the planes of an MHI (see [`check_path`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PathClearance {
    /// The smallest `(d − n·c) / d` over the path's camera centres `c` and the planes that
    /// hold something (1 at the reference camera; 0 on a plane, negative behind it).
    pub min_relative: f64,
    /// The frame (0-based) and the layer `(normal, depth)` where it is reached.
    pub frame: usize,
    /// See [`PathClearance::frame`].
    pub normal: usize,
    /// See [`PathClearance::frame`].
    pub depth: usize,
}

/// Check that no camera of `path` sits on or behind a plane of `mhi` that holds something (at
/// least [`MIN_PLANE_SHARE`] of its normal's composite in the reference view, see
/// [`reference_shares`]): from there the plane is invisible (the renderer masks it) and what it
/// carries would vanish from the view. Every camera must keep at least [`MIN_PATH_CLEARANCE`] of
/// each such plane's distance between itself and the plane.
///
/// # Errors
/// [`Error::InvalidInput`] naming the first frame too close, the plane and the clearance, or
/// an empty path. `Ok(None)` when no plane holds anything.
pub fn check_path(mhi: &Mhi, path: &[Camera]) -> Result<Option<PathClearance>> {
    if path.is_empty() {
        return Err(Error::InvalidInput("the camera path is empty".into()));
    }
    let reference = mhi.reference();
    let shares = reference_shares(mhi);
    let mut worst: Option<PathClearance> = None;
    for (frame, cam) in path.iter().enumerate() {
        let c = reference
            .cam_from_world
            .transform_point(cam.center_in_world());
        for normal in 0..mhi.n() {
            for depth in 0..mhi.d() {
                if shares[normal * mhi.d() + depth] < MIN_PLANE_SHARE {
                    continue;
                }
                let plane = mhi.plane(normal, depth);
                let rel = plane.signed_distance(c) / plane.d();
                if !(rel >= MIN_PATH_CLEARANCE) {
                    let n = plane.normal();
                    return Err(Error::InvalidInput(format!(
                        "camera {} of {} of the path is {} the plane of normal ({:+.2}, {:+.2}, {:+.2}) at depth {:.3}, which holds {:.0} % of what that normal shows (it keeps {:.1} % of the plane's distance; at least {:.0} % is needed, or what the plane holds would vanish from the view): shorten the path (a smaller radius or distance)",
                        frame + 1,
                        path.len(),
                        if rel > 0.0 {
                            "too close to"
                        } else if rel == 0.0 {
                            "on"
                        } else {
                            "behind"
                        },
                        n.x,
                        n.y,
                        n.z,
                        plane.axis_depth(),
                        100.0 * shares[normal * mhi.d() + depth],
                        100.0 * rel,
                        100.0 * MIN_PATH_CLEARANCE
                    )));
                }
                if worst.is_none_or(|w| rel < w.min_relative) {
                    worst = Some(PathClearance {
                        min_relative: rel,
                        frame,
                        normal,
                        depth,
                    });
                }
            }
        }
    }
    Ok(worst)
}

/// [`analyse`] one view at a time, so that a plan over any number of views holds one view's
/// weights at a time: [`ViewsSeen::add`] each view, then [`ViewsSeen::finish`].
#[derive(Debug, Clone)]
pub struct ViewsSeen {
    n: usize,
    prune: Prune,
    any: bool,
    count: usize,
    kept_by_some: Vec<bool>,
    max_weight: Vec<f32>,
    dropped_worst: f32,
}

impl ViewsSeen {
    /// No view seen yet, for `mhi` within `prune`'s budget.
    pub fn new(mhi: &Mhi, prune: Prune) -> Self {
        let n = mhi.n();
        Self {
            n,
            prune,
            any: false,
            count: 0,
            kept_by_some: vec![false; n],
            max_weight: vec![0.0; n],
            dropped_worst: 0.0,
        }
    }

    /// Take one view with its blend weights (`N × H × W`).
    ///
    /// # Errors
    /// When the weights do not have `N × H × W` entries.
    pub fn add(&mut self, cam: &Camera, w: &[f32]) -> Result<()> {
        let n = self.n;
        let px = cam.width as usize * cam.height as usize;
        if w.len() != n * px {
            return Err(Error::InvalidInput(format!(
                "blend weights of a {}x{} view: {} values for {n} normals, expected {}",
                cam.width,
                cam.height,
                w.len(),
                n * px
            )));
        }
        let (active, dropped) = normals_to_drop(w, n, px, self.prune.normal_share());
        for i in 0..n {
            self.kept_by_some[i] |= active[i];
            self.max_weight[i] = w[i * px..(i + 1) * px]
                .iter()
                .fold(self.max_weight[i], |m, v| m.max(*v));
        }
        self.dropped_worst = self.dropped_worst.max(dropped);
        self.any = true;
        self.count += 1;
        Ok(())
    }

    /// The plan for every view added.
    ///
    /// # Errors
    /// Never for a consistent MHI (the signature leaves room for the layer analysis).
    pub fn finish(self, mhi: &Mhi) -> Result<ScenePlan> {
        let prune = self.prune;
        let (n, d) = (mhi.n(), mhi.d());
        let normal_share = prune.normal_share();
        let mut kept_by_some = self.kept_by_some;
        let max_weight = self.max_weight;
        let dropped_worst = self.dropped_worst;
        let no_views = !self.any;
        let count = self.count;
        // Every view's layer share is at least this one (they dropped no more weight than the
        // worst), so what the plan leaves out, every view's render leaves out too.
        let (share, stop) = prune.shares_after(dropped_worst);
        if no_views {
            kept_by_some.fill(true);
        }
        let depths = mhi.depths().to_vec();
        let ref_px = mhi.reference().width as usize * mhi.reference().height as usize;
        let mut per_normal = Vec::with_capacity(n);
        let mut layers_kept = 0;
        let mut mass_worst = 0.0_f32;
        let mut kept_layers_of = Vec::with_capacity(n);
        for i in 0..n {
            let (skip, mass) = layers_to_skip(mhi, i, |_| true, share);
            let empty = (1..d).filter(|&j| mhi.layer_max_alpha(i, j) == 0.0).count();
            let skipped = skip.iter().filter(|s| **s).count();
            let dropped = !kept_by_some[i];
            let kept: Vec<usize> = (1..d).filter(|&j| !skip[j]).collect();
            let occupied = (!kept.is_empty()).then(|| {
                let ds: Vec<f64> = kept.iter().map(|&j| depths[j]).collect();
                [
                    ds.iter().cloned().fold(f64::INFINITY, f64::min),
                    ds.iter().cloned().fold(0.0, f64::max),
                ]
            });
            let reason = if dropped {
                format!(
                    "left out: its blend weight is at most {:.5} in every view, within the normal share {normal_share:.5}",
                    max_weight[i]
                )
            } else {
                mass_worst = mass_worst.max(mass);
                layers_kept += d - skipped;
                kept_layers_of.push((i, skip.clone()));
                format!(
                    "kept (weight up to {:.3}); {skipped} of {} layers left out ({empty} empty), their alphas summing to {mass:.5}; {}",
                    max_weight[i],
                    d,
                    match occupied {
                        Some([a, b]) => format!("occupied depths {a:.3} to {b:.3}"),
                        None => "only the far plane is occupied".into(),
                    }
                )
            };
            let nv = mhi.normals().normals()[i];
            per_normal.push(NormalUse {
                index: i,
                normal: [nv.x, nv.y, nv.z],
                max_weight: max_weight[i],
                dropped,
                layers_empty: empty,
                layers_skipped: skipped,
                skipped_mass: mass,
                occupied_depths: occupied,
                kept_depths: if dropped {
                    Vec::new()
                } else {
                    (0..d).filter(|&j| !skip[j]).collect()
                },
                reason,
            });
        }
        // Reference pixels with nothing in front of the far plane in any kept normal.
        let mut background = 0usize;
        for p in 0..ref_px {
            let front: f32 = kept_layers_of
                .iter()
                .flat_map(|(i, skip)| {
                    (1..d)
                        .filter(move |&j| !skip[j])
                        .map(move |j| mhi.alpha_layer(*i, j)[p])
                })
                .sum();
            if front <= share {
                background += 1;
            }
        }
        let colour_per_layer = match mhi.color() {
            LayerColor::Shared(_) => 0,
            LayerColor::PerLayer(_) => 3,
        };
        let shared_colour = if colour_per_layer == 0 {
            3 * ref_px * 4
        } else {
            0
        };
        let layer_bytes = ref_px * 4 * (1 + colour_per_layer);
        Ok(ScenePlan {
            budget: prune.budget,
            views: count,
            normals: n,
            planes: d,
            per_normal,
            layers_kept,
            background_fraction: background as f64 / ref_px.max(1) as f64,
            bytes_exact: shared_colour + n * d * layer_bytes,
            bytes_kept: shared_colour + layers_kept * layer_bytes,
            bound: mass_worst + dropped_worst + stop,
        })
    }
}
