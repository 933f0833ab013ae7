//! Synthetic posed scenes with exact ground truth: rooms and courtyards of textured planar
//! rectangles (floor, walls, ceiling, slanted panels, boxes, thin poles), procedural textures,
//! and camera clips that translate and rotate. Rendered by exact ray–plane intersection with
//! supersampling and written in RealEstate10K layout plus a `scene.json` of the planes.

use std::f64::consts::PI;
use std::path::{Path, PathBuf};

use glam::{DMat3, DVec2, DVec3};
use image::Rgb32FImage;
use mhi_geom::{Camera, Intrinsics, RigidTransform};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::re10k::{CameraFile, CameraRow};

/// Parameters of a synthetic dataset.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SynthConfig {
    /// Number of scenes (one sequence each).
    pub scenes: usize,
    /// Frames per sequence.
    pub frames: usize,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Master seed; scene `i` is a pure function of `(seed, i)`.
    pub seed: u64,
    /// Fraction of scenes written to the `test` split (the rest go to `train`); at least one
    /// scene goes to each split when there are two or more scenes.
    pub test_fraction: f64,
    /// Fraction of scenes written to the `val` split (validation: what picks a default looks
    /// here, never at `test`); taken from the scenes before the test ones, leaving at least one
    /// scene for `train`.
    pub val_fraction: f64,
    /// Samples per pixel along each axis (2 → 4 samples per pixel).
    pub supersample: u32,
}

impl Default for SynthConfig {
    fn default() -> Self {
        Self {
            scenes: 100,
            frames: 10,
            width: 256,
            height: 256,
            seed: 0,
            test_fraction: 0.2,
            val_fraction: 0.1,
            supersample: 2,
        }
    }
}

impl SynthConfig {
    fn validate(&self) -> Result<()> {
        let bad = |m: String| Err(Error::InvalidArgument(m));
        if self.scenes == 0 {
            return bad("at least one scene is needed".into());
        }
        if self.frames < 3 {
            return bad(format!(
                "a clip needs at least 3 frames to form a triplet, got {}",
                self.frames
            ));
        }
        if self.width == 0 || self.height == 0 || self.width > 8192 || self.height > 8192 {
            return bad(format!(
                "image size {}×{} must be between 1 and 8192 pixels",
                self.width, self.height
            ));
        }
        if !(0.0..=1.0).contains(&self.test_fraction) {
            return bad(format!(
                "test fraction {} must lie in [0, 1]",
                self.test_fraction
            ));
        }
        if !(0.0..=1.0).contains(&self.val_fraction) || self.val_fraction + self.test_fraction > 1.0
        {
            return bad(format!(
                "validation fraction {} must lie in [0, 1] and leave room for the test fraction {}",
                self.val_fraction, self.test_fraction
            ));
        }
        if !(1..=8).contains(&self.supersample) {
            return bad(format!(
                "supersampling {} must be between 1 and 8",
                self.supersample
            ));
        }
        Ok(())
    }

    /// Number of scenes in the validation split (0 when fewer than two scenes are left after
    /// the test split: training keeps at least one).
    pub fn val_scenes(&self) -> usize {
        let left = self.scenes - self.test_scenes();
        let n = (self.scenes as f64 * self.val_fraction).round() as usize;
        if self.val_fraction > 0.0 && left >= 2 {
            n.clamp(1, left - 1)
        } else {
            0
        }
    }

    /// Number of scenes in the test split.
    pub fn test_scenes(&self) -> usize {
        let n = (self.scenes as f64 * self.test_fraction).round() as usize;
        if self.scenes >= 2 && self.test_fraction > 0.0 && self.test_fraction < 1.0 {
            n.clamp(1, self.scenes - 1)
        } else {
            n.min(self.scenes)
        }
    }
}

/// A procedural texture, a function of the position `(a, b)` in metres on its surface.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "lowercase")]
pub enum Texture {
    /// Running-bond bricks of `size` metres with mortar lines of width `mortar`.
    Bricks {
        /// Brick width and height.
        size: [f64; 2],
        /// Mortar width.
        mortar: f64,
        /// Brick colour.
        brick: [f32; 3],
        /// Mortar colour.
        joint: [f32; 3],
    },
    /// A checkerboard of `size`-metre squares.
    Checker {
        /// Square side.
        size: f64,
        /// First colour.
        a: [f32; 3],
        /// Second colour.
        b: [f32; 3],
    },
    /// Stripes of `period` metres at `angle` radians.
    Stripes {
        /// Stripe period.
        period: f64,
        /// Stripe direction.
        angle: f64,
        /// First colour.
        a: [f32; 3],
        /// Second colour.
        b: [f32; 3],
    },
    /// Three octaves of value noise with features of `scale` metres.
    Noise {
        /// Feature size.
        scale: f64,
        /// Lattice seed.
        seed: u32,
        /// Colour at 0.
        a: [f32; 3],
        /// Colour at 1.
        b: [f32; 3],
    },
    /// A linear gradient along `dir` over `length` metres, with faint value noise.
    Gradient {
        /// Direction in surface coordinates.
        dir: [f64; 2],
        /// Length over which the colour goes from `a` to `b`.
        length: f64,
        /// Start colour.
        a: [f32; 3],
        /// End colour.
        b: [f32; 3],
    },
}

fn mix(a: [f32; 3], b: [f32; 3], t: f64) -> [f32; 3] {
    let t = t.clamp(0.0, 1.0) as f32;
    [
        a[0] + (b[0] - a[0]) * t,
        a[1] + (b[1] - a[1]) * t,
        a[2] + (b[2] - a[2]) * t,
    ]
}

fn hash2(x: i64, y: i64, seed: u32) -> f64 {
    let mut h = (x as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (y as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
        ^ u64::from(seed).wrapping_mul(0x1656_67B1_9E37_79F9);
    h ^= h >> 31;
    h = h.wrapping_mul(0xBF58_476D_1CE4_E5B9);
    h ^= h >> 29;
    (h >> 11) as f64 / (1u64 << 53) as f64
}

fn value_noise(p: DVec2, seed: u32) -> f64 {
    let (fx, fy) = (p.x.floor(), p.y.floor());
    let (ix, iy) = (fx as i64, fy as i64);
    let (tx, ty) = (p.x - fx, p.y - fy);
    let s = |t: f64| t * t * (3.0 - 2.0 * t);
    let (sx, sy) = (s(tx), s(ty));
    let v00 = hash2(ix, iy, seed);
    let v10 = hash2(ix + 1, iy, seed);
    let v01 = hash2(ix, iy + 1, seed);
    let v11 = hash2(ix + 1, iy + 1, seed);
    let top = v00 + (v10 - v00) * sx;
    let bot = v01 + (v11 - v01) * sx;
    top + (bot - top) * sy
}

impl Texture {
    /// Colour at surface position `(a, b)` metres.
    pub fn eval(&self, p: DVec2) -> [f32; 3] {
        match self {
            Texture::Bricks {
                size,
                mortar,
                brick,
                joint,
            } => {
                let row = (p.y / size[1]).floor();
                let x = p.x / size[0] + if row as i64 % 2 == 0 { 0.0 } else { 0.5 };
                let (fx, fy) = (x - x.floor(), p.y / size[1] - row);
                let (mx, my) = (mortar / size[0], mortar / size[1]);
                if fx < mx || fy < my {
                    *joint
                } else {
                    // Slight per-brick variation.
                    let v = hash2(x.floor() as i64, row as i64, 7) as f32 * 0.25 + 0.85;
                    [brick[0] * v, brick[1] * v, brick[2] * v]
                }
            }
            Texture::Checker { size, a, b } => {
                let k = (p.x / size).floor() as i64 + (p.y / size).floor() as i64;
                if k.rem_euclid(2) == 0 { *a } else { *b }
            }
            Texture::Stripes {
                period,
                angle,
                a,
                b,
            } => {
                let s = p.x * angle.cos() + p.y * angle.sin();
                if (s / period).rem_euclid(1.0) < 0.5 {
                    *a
                } else {
                    *b
                }
            }
            Texture::Noise { scale, seed, a, b } => {
                let q = p / *scale;
                let n = 0.55 * value_noise(q, *seed)
                    + 0.3 * value_noise(q * 2.03, seed + 1)
                    + 0.15 * value_noise(q * 4.1, seed + 2);
                mix(*a, *b, (n - 0.2) / 0.6)
            }
            Texture::Gradient { dir, length, a, b } => {
                let t = (p.x * dir[0] + p.y * dir[1]) / length;
                let n = value_noise(p * 3.0, 99) * 0.08 - 0.04;
                mix(*a, *b, t + n)
            }
        }
    }
}

/// A textured rectangle `corner + a·û + b·v̂`, `0 ≤ a ≤ |edge_u|`, `0 ≤ b ≤ |edge_v|`, in world
/// coordinates. Its plane is `normal · X = offset` with `normal = û × v̂`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Surface {
    /// What the surface is (`floor`, `wall`, `ceiling`, `panel`, `box`, `pole`, `sky`).
    pub kind: String,
    /// One corner.
    pub corner: DVec3,
    /// First edge from the corner.
    pub edge_u: DVec3,
    /// Second edge from the corner, orthogonal to the first.
    pub edge_v: DVec3,
    /// Unit normal `edge_u × edge_v / ‖…‖` (world frame).
    pub normal: DVec3,
    /// Plane offset: `normal · X = offset` on the surface (world frame).
    pub offset: f64,
    /// The texture.
    pub texture: Texture,
}

impl Surface {
    fn new(kind: &str, corner: DVec3, edge_u: DVec3, edge_v: DVec3, texture: Texture) -> Self {
        let normal = edge_u.cross(edge_v).normalize();
        Self {
            kind: kind.into(),
            corner,
            edge_u,
            edge_v,
            normal,
            offset: normal.dot(corner),
            texture,
        }
    }

    /// Ray parameter and surface coordinates of the hit of `origin + s·dir`, if any (`s > 1e-9`).
    pub fn intersect(&self, origin: DVec3, dir: DVec3) -> Option<(f64, DVec2)> {
        let denom = self.normal.dot(dir);
        if denom.abs() < 1e-12 {
            return None;
        }
        let s = (self.offset - self.normal.dot(origin)) / denom;
        if !(s > 1e-9) {
            return None;
        }
        let rel = origin + dir * s - self.corner;
        let (lu, lv) = (self.edge_u.length_squared(), self.edge_v.length_squared());
        let (a, b) = (rel.dot(self.edge_u) / lu, rel.dot(self.edge_v) / lv);
        ((0.0..=1.0).contains(&a) && (0.0..=1.0).contains(&b))
            .then(|| (s, DVec2::new(a * lu.sqrt(), b * lv.sqrt())))
    }
}

/// The nearest surface hit by a ray.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Index into [`Scene::surfaces`].
    pub surface: usize,
    /// Ray parameter (distance when `dir` is unit).
    pub s: f64,
    /// Surface coordinates in metres.
    pub uv: DVec2,
}

/// A synthetic scene: its surfaces, its light and its camera clip.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Scene {
    /// Sequence name.
    pub name: String,
    /// `room` or `courtyard`.
    pub kind: String,
    /// Seed the scene was drawn from.
    pub seed: u64,
    /// Unit direction towards the light (world frame), for view-independent Lambert shading.
    pub light: DVec3,
    /// The surfaces.
    pub surfaces: Vec<Surface>,
    /// One camera per frame (world-to-camera poses).
    pub cameras: Vec<Camera>,
    /// One timestamp (µs) per frame.
    pub timestamps: Vec<u64>,
}

impl Scene {
    /// The nearest hit of `origin + s·dir`, `s > 0`.
    pub fn trace(&self, origin: DVec3, dir: DVec3) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        for (i, srf) in self.surfaces.iter().enumerate() {
            if let Some((s, uv)) = srf.intersect(origin, dir)
                && best.is_none_or(|b| s < b.s)
            {
                best = Some(Hit { surface: i, s, uv });
            }
        }
        best
    }

    /// Radiance of a hit (view-independent: texture times two-sided Lambert plus ambient).
    pub fn shade(&self, hit: &Hit) -> [f32; 3] {
        let srf = &self.surfaces[hit.surface];
        let c = srf.texture.eval(hit.uv);
        let lambert = (0.55 + 0.45 * srf.normal.dot(self.light).abs()) as f32;
        [
            (c[0] * lambert).clamp(0.0, 1.0),
            (c[1] * lambert).clamp(0.0, 1.0),
            (c[2] * lambert).clamp(0.0, 1.0),
        ]
    }

    /// Colour seen along a ray; black where nothing is hit (scenes are closed, so never).
    pub fn radiance(&self, origin: DVec3, dir: DVec3) -> [f32; 3] {
        self.trace(origin, dir).map_or([0.0; 3], |h| self.shade(&h))
    }

    /// Render frame `index` with `ss × ss` stratified samples per pixel.
    pub fn render(&self, index: usize, ss: u32) -> Rgb32FImage {
        let cam = &self.cameras[index];
        let world_from_cam = cam.cam_from_world.inverse();
        let origin = world_from_cam.translation();
        let ss = ss.max(1);
        let inv = 1.0 / f64::from(ss * ss);
        Rgb32FImage::from_fn(cam.width, cam.height, |x, y| {
            let mut acc = [0.0_f64; 3];
            for sy in 0..ss {
                for sx in 0..ss {
                    let u = DVec2::new(
                        f64::from(x) + (f64::from(sx) + 0.5) / f64::from(ss),
                        f64::from(y) + (f64::from(sy) + 0.5) / f64::from(ss),
                    );
                    let dir = world_from_cam.transform_vector(cam.intrinsics.ray(u));
                    let c = self.radiance(origin, dir);
                    for k in 0..3 {
                        acc[k] += f64::from(c[k]);
                    }
                }
            }
            image::Rgb([
                (acc[0] * inv) as f32,
                (acc[1] * inv) as f32,
                (acc[2] * inv) as f32,
            ])
        })
    }

    /// Exact ground truth at the centre of every pixel of `camera` (row-major): the unit normal
    /// of the surface seen, in the camera frame, and its depth (camera z). `None` where the ray
    /// hits nothing (never in a closed scene).
    pub fn ground_truth(&self, camera: &Camera) -> Vec<Option<(DVec3, f64)>> {
        let world_from_cam = camera.cam_from_world.inverse();
        let origin = world_from_cam.translation();
        (0..camera.height)
            .flat_map(|y| (0..camera.width).map(move |x| (x, y)))
            .map(|(x, y)| {
                let ray = camera.intrinsics.ray(mhi_geom::pixel_center(x, y));
                let hit = self.trace(origin, world_from_cam.transform_vector(ray))?;
                let n = camera
                    .cam_from_world
                    .transform_vector(self.surfaces[hit.surface].normal);
                Some((n, hit.s))
            })
            .collect()
    }

    /// The camera file of the clip (normalised intrinsics, world-to-camera poses).
    pub fn camera_file(&self) -> Result<CameraFile> {
        let rows = self
            .cameras
            .iter()
            .zip(&self.timestamps)
            .map(|(c, &timestamp)| {
                let intrinsics =
                    c.intrinsics
                        .to_normalized(c.width, c.height)
                        .map_err(|source| Error::Geometry {
                            context: format!("intrinsics of {}", self.name),
                            source,
                        })?;
                Ok(CameraRow {
                    timestamp,
                    intrinsics,
                    distortion: [0.0; 2],
                    cam_from_world: c.cam_from_world,
                })
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(CameraFile {
            url: format!("synthetic://mhi-data/{}/seed={}", self.kind, self.seed),
            rows,
            rotation_warning: None,
        })
    }
}

fn rand_color(rng: &mut impl Rng, lo: f32, hi: f32) -> [f32; 3] {
    [
        rng.random_range(lo..hi),
        rng.random_range(lo..hi),
        rng.random_range(lo..hi),
    ]
}

fn rand_texture(rng: &mut impl Rng) -> Texture {
    let a = rand_color(rng, 0.05, 0.55);
    let b = rand_color(rng, 0.45, 0.95);
    match rng.random_range(0..5) {
        0 => Texture::Bricks {
            size: [rng.random_range(0.2..0.45), rng.random_range(0.08..0.16)],
            mortar: rng.random_range(0.015..0.03),
            brick: rand_color(rng, 0.35, 0.85),
            joint: rand_color(rng, 0.6, 0.9),
        },
        1 => Texture::Checker {
            size: rng.random_range(0.15..0.5),
            a,
            b,
        },
        2 => Texture::Stripes {
            period: rng.random_range(0.1..0.5),
            angle: rng.random_range(0.0..PI),
            a,
            b,
        },
        3 => Texture::Noise {
            scale: rng.random_range(0.05..0.4),
            seed: rng.random(),
            a,
            b,
        },
        _ => Texture::Gradient {
            dir: {
                let t: f64 = rng.random_range(0.0..2.0 * PI);
                [t.cos(), t.sin()]
            },
            length: rng.random_range(1.0..5.0),
            a,
            b,
        },
    }
}

/// Two unit vectors spanning the plane orthogonal to `n`.
fn basis(n: DVec3) -> (DVec3, DVec3) {
    let helper = if n.y.abs() < 0.9 { DVec3::Y } else { DVec3::X };
    let u = helper.cross(n).normalize();
    (u, n.cross(u))
}

/// An axis-aligned (in its own yaw) box resting on the floor `y = floor_y` (world y points down).
fn push_box(
    out: &mut Vec<Surface>,
    kind: &str,
    center_xz: DVec2,
    size: DVec3,
    yaw: f64,
    floor_y: f64,
    texture: &Texture,
) {
    let r = DMat3::from_rotation_y(yaw);
    let ex = r * DVec3::new(size.x, 0.0, 0.0);
    let ez = r * DVec3::new(0.0, 0.0, size.z);
    let up = DVec3::new(0.0, -size.y, 0.0);
    let c0 = DVec3::new(center_xz.x, floor_y, center_xz.y) - ex * 0.5 - ez * 0.5;
    // Four sides and the top (shading is two-sided, so face orientation does not matter).
    out.push(Surface::new(kind, c0, up, ex, texture.clone()));
    out.push(Surface::new(kind, c0 + ez, ex, up, texture.clone()));
    out.push(Surface::new(kind, c0, ez, up, texture.clone()));
    out.push(Surface::new(kind, c0 + ex, up, ez, texture.clone()));
    out.push(Surface::new(kind, c0 + up, ez, ex, texture.clone()));
}

/// Per-scene seed from the master seed and the scene index (SplitMix64).
fn scene_seed(seed: u64, index: usize) -> u64 {
    let mut z = seed
        .wrapping_add(0x9E37_79B9_7F4A_7C15)
        .wrapping_add((index as u64).wrapping_mul(0xD1B5_4A32_D192_ED03));
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Draw scene `index` of `config` (rooms and courtyards alternate at random, 70 / 30).
pub fn make_scene(config: &SynthConfig, index: usize) -> Result<Scene> {
    let seed = scene_seed(config.seed, index);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let courtyard = rng.random_bool(0.3);
    let floor_y: f64 = rng.random_range(1.3..1.8);
    // World frame: x right, y down, z forward; the clip starts near the origin looking along +z.
    let mut surfaces = if courtyard {
        courtyard_surfaces(&mut rng, floor_y)
    } else {
        room_surfaces(&mut rng, floor_y)
    };
    let clip = camera_clip(&mut rng, config)?;
    add_props(&mut rng, &mut surfaces, &clip, floor_y, courtyard);
    let light = DVec3::new(
        rng.random_range(-0.6..0.6),
        -1.0,
        rng.random_range(-0.6..0.6),
    )
    .normalize();
    let timestamps = (0..config.frames as u64)
        .map(|f| 1_000_000 + f * 33_367)
        .collect();
    Ok(Scene {
        name: format!("scene_{index:05}"),
        kind: if courtyard { "courtyard" } else { "room" }.into(),
        seed,
        light,
        surfaces,
        cameras: clip.cameras,
        timestamps,
    })
}

/// A courtyard: a floor, three walls and a sky box (the random draws of a scene, in order).
fn courtyard_surfaces(rng: &mut ChaCha8Rng, floor_y: f64) -> Vec<Surface> {
    let mut surfaces = Vec::new();
    let half_w: f64 = rng.random_range(4.0..7.0);
    let back: f64 = rng.random_range(11.0..18.0);
    let h_l: f64 = rng.random_range(5.0..10.0);
    let h_r: f64 = rng.random_range(5.0..10.0);
    let h_b: f64 = rng.random_range(5.0..10.0);
    let big = 60.0;
    let tex = |rng: &mut ChaCha8Rng| rand_texture(rng);
    surfaces.push(Surface::new(
        "floor",
        DVec3::new(-big, floor_y, -big),
        DVec3::Z * 2.0 * big,
        DVec3::X * 2.0 * big,
        tex(rng),
    ));
    let y = |h: f64| DVec3::new(0.0, -h, 0.0);
    surfaces.push(Surface::new(
        "wall",
        DVec3::new(-half_w, floor_y, -4.0),
        y(h_l),
        DVec3::Z * (back + 4.0),
        tex(rng),
    ));
    surfaces.push(Surface::new(
        "wall",
        DVec3::new(half_w, floor_y, -4.0),
        DVec3::Z * (back + 4.0),
        y(h_r),
        tex(rng),
    ));
    surfaces.push(Surface::new(
        "wall",
        DVec3::new(-half_w, floor_y, back),
        DVec3::X * 2.0 * half_w,
        y(h_b),
        tex(rng),
    ));
    // Sky: five faces of a large box closed by the floor.
    let sky = Texture::Gradient {
        dir: [0.0, 1.0],
        length: big,
        a: [0.55, 0.7, 0.95],
        b: [0.95, 0.97, 1.0],
    };
    let lo = DVec3::new(-big, floor_y, -big);
    let h = y(big);
    surfaces.push(Surface::new(
        "sky",
        lo + DVec3::Z * 2.0 * big,
        DVec3::X * 2.0 * big,
        h,
        sky.clone(),
    ));
    surfaces.push(Surface::new(
        "sky",
        lo,
        h,
        DVec3::X * 2.0 * big,
        sky.clone(),
    ));
    surfaces.push(Surface::new(
        "sky",
        lo,
        DVec3::Z * 2.0 * big,
        h,
        sky.clone(),
    ));
    surfaces.push(Surface::new(
        "sky",
        lo + DVec3::X * 2.0 * big,
        h,
        DVec3::Z * 2.0 * big,
        sky.clone(),
    ));
    surfaces.push(Surface::new(
        "sky",
        lo + h,
        DVec3::X * 2.0 * big,
        DVec3::Z * 2.0 * big,
        sky,
    ));
    surfaces
}

/// A closed room: floor, ceiling and four walls.
fn room_surfaces(rng: &mut ChaCha8Rng, floor_y: f64) -> Vec<Surface> {
    let mut surfaces = Vec::new();
    let half_w: f64 = rng.random_range(3.0..5.0);
    let back: f64 = rng.random_range(7.0..11.0);
    let front = -3.0;
    let height: f64 = rng.random_range(2.6..3.6);
    let ceil_y = floor_y - height;
    let len = back - front;
    let yv = DVec3::new(0.0, -height, 0.0);
    surfaces.push(Surface::new(
        "floor",
        DVec3::new(-half_w, floor_y, front),
        DVec3::Z * len,
        DVec3::X * 2.0 * half_w,
        rand_texture(rng),
    ));
    surfaces.push(Surface::new(
        "ceiling",
        DVec3::new(-half_w, ceil_y, front),
        DVec3::X * 2.0 * half_w,
        DVec3::Z * len,
        rand_texture(rng),
    ));
    surfaces.push(Surface::new(
        "wall",
        DVec3::new(-half_w, floor_y, front),
        yv,
        DVec3::Z * len,
        rand_texture(rng),
    ));
    surfaces.push(Surface::new(
        "wall",
        DVec3::new(half_w, floor_y, front),
        DVec3::Z * len,
        yv,
        rand_texture(rng),
    ));
    surfaces.push(Surface::new(
        "wall",
        DVec3::new(-half_w, floor_y, back),
        DVec3::X * 2.0 * half_w,
        yv,
        rand_texture(rng),
    ));
    surfaces.push(Surface::new(
        "wall",
        DVec3::new(-half_w, floor_y, front),
        yv,
        DVec3::X * 2.0 * half_w,
        rand_texture(rng),
    ));
    surfaces
}

/// A camera clip and where the props may stand.
struct Clip {
    cameras: Vec<Camera>,
    centers: Vec<DVec3>,
    /// The clip's middle position and viewing direction.
    mid: DVec3,
    forward: DVec3,
}

/// The camera clip: a start pose, then a straight translation and a steady yaw/pitch change.
fn camera_clip(rng: &mut ChaCha8Rng, config: &SynthConfig) -> Result<Clip> {
    let start = DVec3::new(
        rng.random_range(-0.8..0.8),
        rng.random_range(-0.2..0.2),
        rng.random_range(-0.5..0.5),
    );
    let travel_dir = DVec3::new(
        rng.random_range(-1.0..1.0),
        rng.random_range(-0.2..0.2),
        rng.random_range(-0.6..1.0),
    )
    .normalize();
    let travel: f64 = rng.random_range(0.3..1.0);
    let yaw0: f64 = rng.random_range(-12.0_f64..12.0).to_radians();
    let pitch0: f64 = rng.random_range(-5.0_f64..5.0).to_radians();
    let sign = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
    let dyaw: f64 = sign * rng.random_range(4.0_f64..16.0).to_radians();
    let dpitch: f64 = rng.random_range(-10.0_f64..10.0).to_radians();
    let fov: f64 = rng.random_range(55.0_f64..75.0).to_radians();
    let (w, h) = (config.width, config.height);
    let fx = 0.5 * f64::from(w) / (fov / 2.0).tan();
    let k = Intrinsics::new(fx, fx, f64::from(w) / 2.0, f64::from(h) / 2.0).map_err(|source| {
        Error::Geometry {
            context: "synthetic intrinsics".into(),
            source,
        }
    })?;
    let n = config.frames;
    let mut cameras = Vec::with_capacity(n);
    let mut centers = Vec::with_capacity(n);
    for f in 0..n {
        let s = if n > 1 {
            f as f64 / (n - 1) as f64
        } else {
            0.0
        };
        let center = start + travel_dir * travel * s;
        // world_from_cam rotation: yaw about y, then pitch about x.
        let world_from_cam_r =
            DMat3::from_rotation_y(yaw0 + dyaw * s) * DMat3::from_rotation_x(pitch0 + dpitch * s);
        let cam_from_world = RigidTransform::new(
            world_from_cam_r.transpose(),
            -(world_from_cam_r.transpose() * center),
        )
        .map_err(|source| Error::Geometry {
            context: "synthetic pose".into(),
            source,
        })?;
        centers.push(center);
        cameras.push(
            Camera::new(k, cam_from_world, w, h).map_err(|source| Error::Geometry {
                context: "synthetic camera".into(),
                source,
            })?,
        );
    }
    Ok(Clip {
        cameras,
        centers,
        mid: start + travel_dir * travel * 0.5,
        forward: DMat3::from_rotation_y(yaw0 + dyaw * 0.5) * DVec3::Z,
    })
}

/// Props in view of the clip, clear of every camera: slanted panels, boxes and thin poles.
fn add_props(
    rng: &mut ChaCha8Rng,
    surfaces: &mut Vec<Surface>,
    clip: &Clip,
    floor_y: f64,
    courtyard: bool,
) {
    let (forward, mid, centers) = (clip.forward, clip.mid, &clip.centers);
    // Clearance from every camera position.
    let clear = |p: DVec3, r: f64| {
        centers
            .iter()
            .all(|c| (DVec2::new(c.x - p.x, c.z - p.z)).length() > r + 1.2)
    };
    let in_view_point = |rng: &mut ChaCha8Rng, dmin: f64, dmax: f64| {
        let dist = rng.random_range(dmin..dmax);
        let side = DVec3::new(forward.z, 0.0, -forward.x);
        mid + forward * dist + side * rng.random_range(-0.45..0.45) * dist
    };

    // Slanted panels at 20–70° to the view.
    for _ in 0..rng.random_range(2..=4) {
        let c = in_view_point(rng, 2.5, 6.0);
        let c = DVec3::new(c.x, floor_y - rng.random_range(0.6..1.8), c.z);
        let (sw, sh): (f64, f64) = (rng.random_range(0.7..2.0), rng.random_range(0.7..2.0));
        if !clear(c, sw.max(sh) / 2.0) {
            continue;
        }
        let to_cam = (mid - c).normalize();
        let (b1, b2) = basis(to_cam);
        let phi: f64 = rng.random_range(0.0..2.0 * PI);
        let axis = b1 * phi.cos() + b2 * phi.sin();
        let tilt: f64 = rng.random_range(20.0_f64..70.0).to_radians();
        let n = DMat3::from_axis_angle(axis, tilt) * to_cam;
        let (u, v) = basis(n);
        let corner = c - u * sw / 2.0 - v * sh / 2.0;
        surfaces.push(Surface::new(
            "panel",
            corner,
            u * sw,
            v * sh,
            rand_texture(rng),
        ));
    }
    // Boxes on the floor.
    for _ in 0..rng.random_range(1..=3) {
        let c = in_view_point(rng, 3.0, 7.5);
        let size = DVec3::new(
            rng.random_range(0.5..1.5),
            rng.random_range(0.4..1.4),
            rng.random_range(0.5..1.5),
        );
        if !clear(c, size.x.max(size.z)) {
            continue;
        }
        let tex = rand_texture(rng);
        push_box(
            surfaces,
            "box",
            DVec2::new(c.x, c.z),
            size,
            rng.random_range(0.0..PI),
            floor_y,
            &tex,
        );
    }
    // Thin poles.
    for _ in 0..rng.random_range(1..=3) {
        let c = in_view_point(rng, 2.5, 8.0);
        let t: f64 = rng.random_range(0.04..0.1);
        if !clear(c, t) {
            continue;
        }
        let tex = rand_texture(rng);
        let height = if courtyard {
            rng.random_range(2.0..4.0)
        } else {
            floor_y + 3.6
        };
        push_box(
            surfaces,
            "pole",
            DVec2::new(c.x, c.z),
            DVec3::new(t, height, t),
            rng.random_range(0.0..PI),
            floor_y,
            &tex,
        );
    }
}

/// What [`generate`] wrote.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SynthSummary {
    /// Sequences written to `train`.
    pub train: Vec<String>,
    /// Sequences written to `val`.
    pub val: Vec<String>,
    /// Sequences written to `test`.
    pub test: Vec<String>,
    /// Frames rendered in all.
    pub frames: usize,
}

/// Generate a dataset in RealEstate10K layout under `out`:
/// `out/{train,val,test}/<scene>.txt`, `out/{train,val,test}/<scene>/<timestamp>.png` and
/// `out/{train,val,test}/<scene>/scene.json`. Frames render in parallel; `on_frame` is called after
/// each one (for a progress bar). Existing files with the same names are replaced atomically;
/// callers decide whether `out` may already hold data.
pub fn generate(
    config: &SynthConfig,
    out: &Path,
    on_frame: &(dyn Fn() + Sync),
) -> Result<SynthSummary> {
    config.validate()?;
    // Marks the set as incomplete until the last frame is written: an interrupted run leaves it,
    // and `Dataset::open` then refuses the set instead of quietly training on a fraction of it.
    let marker = out.join(crate::INCOMPLETE_MARKER);
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    crate::write_atomic(
        &marker,
        b"synthetic generation started and has not finished; generate the set again\n",
    )?;
    if crate::output::read_marker(out).is_none() {
        crate::output::mark_dir(out, SYNTH_KIND, false)?;
    }
    let n_test = config.test_scenes();
    let n_val = config.val_scenes();
    let scenes: Vec<(Scene, PathBuf)> = (0..config.scenes)
        .map(|i| {
            let split = if i >= config.scenes - n_test {
                "test"
            } else if i >= config.scenes - n_test - n_val {
                "val"
            } else {
                "train"
            };
            Ok((make_scene(config, i)?, out.join(split)))
        })
        .collect::<Result<_>>()?;
    for (scene, dir) in &scenes {
        let seq_dir = dir.join(&scene.name);
        std::fs::create_dir_all(&seq_dir).map_err(|e| Error::io(&seq_dir, e))?;
        scene
            .camera_file()?
            .write(&dir.join(format!("{}.txt", scene.name)))?;
        let json = serde_json::to_vec_pretty(scene).map_err(|source| Error::Json {
            path: seq_dir.join("scene.json"),
            source,
        })?;
        crate::write_atomic(&seq_dir.join("scene.json"), &json)?;
    }
    let jobs: Vec<(usize, usize)> = (0..scenes.len())
        .flat_map(|s| (0..config.frames).map(move |f| (s, f)))
        .collect();
    jobs.par_iter().try_for_each(|&(s, f)| {
        let (scene, dir) = &scenes[s];
        let img = scene.render(f, config.supersample);
        let path = dir
            .join(&scene.name)
            .join(format!("{}.png", scene.timestamps[f]));
        crate::write_png(&path, &crate::dataset::to_u8(&img))?;
        on_frame();
        Ok::<(), Error>(())
    })?;
    std::fs::remove_file(&marker).map_err(|e| Error::io(&marker, e))?;
    crate::output::mark_dir(out, SYNTH_KIND, true)?;
    let names = |split: &str| {
        scenes
            .iter()
            .filter(|(_, d)| d.ends_with(split))
            .map(|(s, _)| s.name.clone())
            .collect()
    };
    Ok(SynthSummary {
        train: names("train"),
        val: names("val"),
        test: names("test"),
        frames: jobs.len(),
    })
}

/// The kind of output (see [`crate::output`]) a folder [`generate`] wrote is.
pub const SYNTH_KIND: &str = "synthetic dataset";

/// Read a scene's `scene.json`.
pub fn load_scene(path: &Path) -> Result<Scene> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    serde_json::from_slice(&bytes).map_err(|source| Error::Json {
        path: path.to_path_buf(),
        source,
    })
}
