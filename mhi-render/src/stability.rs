//! Numerical stability on stiff and extreme cases: the f32 renderer against the f64 reference,
//! with NaN/Inf counts and whether degenerate geometry was detected and masked.

use glam::{DMat3, DVec3};
use image::Rgb32FImage;
use mhi_geom::{
    BlendHeuristic, Camera, Intrinsics, NormalSet, RigidTransform, depths_linear_in_disparity,
};
use rand::{Rng, SeedableRng};
use serde::{Deserialize, Serialize};

use crate::cpu::{Blend, RenderOptions, render};
use crate::mhi::{LayerColor, Mhi};
use crate::reference::render_f64;

/// Largest accepted `max |f32 − f64|` of a rendered pixel.
///
/// The f32 renderer evaluates each homography in f32: a sample position `p` carries a relative
/// error of a few ulps (6e-8), i.e. `≈ 2e-4` pixels at `p ≈ 2048`; bilinear sampling turns it
/// into a value error of at most that times the image's largest gradient (1 per pixel for random
/// textures), plus compositing rounding over ≤ 256 layers (`≈ 256 · 6e-8`). `2e-3` bounds both
/// with a margin of about 10.
pub const MAX_ABS_ERROR: f64 = 2e-3;

/// One row of the stability table.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct StabilityRow {
    /// What the case stresses.
    pub case: String,
    /// Image size.
    pub size: [u32; 2],
    /// Normals N and planes D.
    pub normals: usize,
    /// Planes per normal.
    pub planes: usize,
    /// Largest absolute difference between the f32 render and the f64 reference.
    pub max_abs_error: f64,
    /// Mean absolute difference.
    pub mean_abs_error: f64,
    /// NaN or infinite values in the f32 output (must be 0).
    pub non_finite: usize,
    /// Layers found invisible from the target (masked).
    pub layers_masked: usize,
    /// Whether the case is degenerate by construction (so masking is expected).
    pub degenerate: bool,
    /// Degenerate geometry was detected and masked (or the case is not degenerate).
    pub detected: bool,
    /// `non_finite == 0 && max_abs_error <= MAX_ABS_ERROR && detected`.
    pub pass: bool,
}

#[derive(Clone, Copy)]
enum Fill {
    Random,
    Zero,
    One,
}

struct Case {
    name: String,
    size: (u32, u32),
    normals: NormalSet,
    near: f64,
    far: f64,
    planes: usize,
    rotation: DMat3,
    translation: DVec3,
    alpha: Fill,
    image: Fill,
    degenerate: bool,
}

fn base(name: &str) -> Case {
    Case {
        name: name.into(),
        size: (48, 36),
        normals: NormalSet::paper(),
        near: 1.0,
        far: 100.0,
        planes: 16,
        rotation: DMat3::from_rotation_y(0.05),
        translation: DVec3::new(0.1, -0.02, 0.05),
        alpha: Fill::Random,
        image: Fill::Random,
        degenerate: false,
    }
}

fn cases() -> Vec<Case> {
    let mut v = Vec::new();
    for deg in [0.0, 1e-6, 10.0, 45.0, 90.0, 179.0] {
        let mut c = base(&format!("rotation {deg}°"));
        c.rotation =
            DMat3::from_axis_angle(DVec3::new(0.3, 1.0, 0.1).normalize(), f64::to_radians(deg));
        v.push(c);
    }
    for t in [1e-9, 1.0, 1e3] {
        let mut c = base(&format!("translation {t:e}"));
        c.translation = DVec3::new(t, 0.0, 0.0);
        c.degenerate = t >= 1.0;
        v.push(c);
    }
    {
        let mut c = base("planes nearly edge-on");
        c.normals = NormalSet::custom(vec![DVec3::new(
            0.999_999,
            0.0,
            (1.0 - 0.999_999_f64.powi(2)).sqrt(),
        )])
        .expect("unit normal");
        c.rotation = DMat3::from_rotation_y(0.3);
        v.push(c);
    }
    // The nearest fronto plane sits at z = near = 1: put the target camera centre at
    // d − nᵀt = 1e-12, 0 and −0.5 from it (X_ref = R X_tgt + t, so the centre is at t).
    for (label, gap) in [("1e-12", 1e-12), ("0", 0.0), ("negative", -0.5)] {
        let mut c = base(&format!("d − nᵀt = {label}"));
        c.normals = NormalSet::paper_subset(1).expect("paper subset");
        c.rotation = DMat3::IDENTITY;
        c.translation = DVec3::new(0.0, 0.0, 1.0 - gap);
        c.degenerate = true;
        v.push(c);
    }
    {
        let mut c = base("near 1e-3, far 1e6");
        c.near = 1e-3;
        c.far = 1e6;
        c.degenerate = true; // the nearest planes are behind a target 0.1 away
        v.push(c);
    }
    for (name, a) in [
        ("all-zero alphas", Fill::Zero),
        ("all-one alphas", Fill::One),
    ] {
        let mut c = base(name);
        c.alpha = a;
        v.push(c);
    }
    for (name, img) in [("black image", Fill::Zero), ("white image", Fill::One)] {
        let mut c = base(name);
        c.image = img;
        v.push(c);
    }
    for size in [(1, 1), (3, 7), (2048, 2048)] {
        let mut c = base(&format!("{}x{} image", size.0, size.1));
        c.size = size;
        if size.0 > 100 {
            c.normals = NormalSet::paper_subset(1).expect("paper subset");
            c.planes = 2;
        }
        v.push(c);
    }
    {
        let mut c = base("N = 1");
        c.normals = NormalSet::paper_subset(1).expect("paper subset");
        v.push(c);
    }
    {
        let mut c = base("N = 9");
        c.normals = NormalSet::custom(
            (0..9)
                .map(|i| {
                    let a = i as f64 * std::f64::consts::TAU / 9.0;
                    DVec3::new(0.6 * a.cos(), 0.6 * a.sin(), 0.8)
                })
                .collect(),
        )
        .expect("unit normals");
        v.push(c);
    }
    for d in [1, 256] {
        let mut c = base(&format!("D = {d}"));
        c.planes = d;
        if d > 100 {
            c.size = (24, 18);
        }
        v.push(c);
    }
    v
}

fn fill(f: Fill, rng: &mut impl Rng) -> f32 {
    match f {
        Fill::Random => rng.random(),
        Fill::Zero => 0.0,
        Fill::One => 1.0,
    }
}

fn run(c: &Case) -> crate::Result<StabilityRow> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let (w, h) = c.size;
    let f = 0.7 * f64::from(w.max(h));
    let k = Intrinsics::new(f, f, f64::from(w) / 2.0, f64::from(h) / 2.0).map_err(geo)?;
    let reference = Camera::new(k, RigidTransform::IDENTITY, w, h).map_err(geo)?;
    // ref_from_tgt = (R, t) as in DESIGN.md, so the target's pose is its inverse.
    let ref_from_tgt = RigidTransform::new(c.rotation, c.translation).map_err(geo)?;
    let target = Camera::new(k, ref_from_tgt.inverse(), w, h).map_err(geo)?;
    let depths = if c.planes == 1 {
        vec![c.far]
    } else {
        depths_linear_in_disparity(c.near, c.far, c.planes).map_err(geo)?
    };
    let image = Rgb32FImage::from_fn(w, h, |_, _| {
        image::Rgb([
            fill(c.image, &mut rng),
            fill(c.image, &mut rng),
            fill(c.image, &mut rng),
        ])
    });
    let alpha = (0..c.normals.len() * depths.len() * (w * h) as usize)
        .map(|_| fill(c.alpha, &mut rng))
        .collect();
    let mhi = Mhi::new(
        c.normals.clone(),
        depths,
        reference,
        LayerColor::Shared(image),
        alpha,
    )?;
    let blend = Blend::Heuristic(BlendHeuristic::Soft);
    let fast = render(
        &mhi,
        &target,
        &RenderOptions {
            blend,
            ..Default::default()
        },
    )?;
    let (slow, _) = render_f64(&mhi, &target, blend)?;
    let mut max: f64 = 0.0;
    let mut sum = 0.0;
    let mut non_finite = 0;
    for (p, q) in fast.image.pixels().zip(&slow) {
        for (a, b) in p.0.iter().zip(q) {
            if !a.is_finite() {
                non_finite += 1;
                continue;
            }
            let e = (f64::from(*a) - b).abs();
            max = max.max(e);
            sum += e;
        }
    }
    let mean = sum / (3 * w * h) as f64;
    let masked = fast.stats.layers_invisible;
    // Degenerate cases must show masking: invisible layers, or (for a target looking away) an
    // image of masked, all-zero samples.
    let detected = !c.degenerate || masked > 0 || fast.image.as_raw().iter().all(|v| *v == 0.0);
    Ok(StabilityRow {
        case: c.name.clone(),
        size: [w, h],
        normals: c.normals.len(),
        planes: mhi.d(),
        max_abs_error: max,
        mean_abs_error: mean,
        non_finite,
        layers_masked: masked,
        degenerate: c.degenerate,
        detected,
        pass: non_finite == 0 && max <= MAX_ABS_ERROR && detected,
    })
}

fn geo(source: mhi_geom::Error) -> crate::Error {
    crate::Error::Geometry {
        context: "stability case".into(),
        source,
    }
}

/// Run every case; `on_case` is called after each (for a progress bar).
pub fn stability_table(on_case: &dyn Fn(&StabilityRow)) -> crate::Result<Vec<StabilityRow>> {
    let mut rows = Vec::new();
    for c in cases() {
        let row = run(&c)?;
        on_case(&row);
        rows.push(row);
    }
    Ok(rows)
}

/// Number of cases in [`stability_table`].
pub fn stability_case_count() -> usize {
    cases().len()
}
