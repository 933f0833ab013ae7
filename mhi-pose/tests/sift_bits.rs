//! The SIFT features `mhi-pose` gets from the patched kornia-imgproc in `third_party/` (its
//! Gaussian passes reordered so that they vectorise) are, to the last bit, those of the
//! crates.io release: the fingerprints below were computed with the unpatched 0.2.0.

use kornia_imgproc::features::{FirstOctave, SiftConfig, SiftWorkspace, sift_detect_and_compute};

/// A textured grey image, 0..255: overlapping blobs and ripples, deterministic.
fn scene(w: usize, h: usize) -> Vec<f32> {
    let mut state = 0x2545_f491_u32;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        f64::from(state) / f64::from(u32::MAX)
    };
    let blobs: Vec<[f64; 4]> = (0..60)
        .map(|_| {
            [
                next() * w as f64,
                next() * h as f64,
                2.0 + 10.0 * next(),
                next() - 0.5,
            ]
        })
        .collect();
    (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f64, (i / w) as f64);
            let mut v = 0.5 + 0.1 * (x * 0.21 + y * 0.07).sin() * (y * 0.13).cos();
            for [bx, by, r, a] in &blobs {
                let d2 = ((x - bx).powi(2) + (y - by).powi(2)) / (r * r);
                v += a * (-d2).exp();
            }
            (255.0 * v.clamp(0.0, 1.0)) as f32
        })
        .collect()
}

/// FNV-1a over every keypoint's fields and every descriptor value, bit for bit.
fn fingerprint(first: FirstOctave) -> (usize, u64) {
    let (w, h) = (160, 120);
    let grey = scene(w, h);
    let mut ws = SiftWorkspace::new();
    let f = sift_detect_and_compute(
        &mut ws,
        &grey,
        w,
        h,
        &SiftConfig::default(),
        first,
        usize::MAX,
        false,
    )
    .expect("SIFT runs");
    let mut hash = 0xcbf2_9ce4_8422_2325_u64;
    let mut eat = |bits: u32| {
        for b in bits.to_le_bytes() {
            hash = (hash ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
        }
    };
    for k in &f.keypoints {
        for v in [k.x, k.y, k.size, k.angle, k.response] {
            eat(v.to_bits());
        }
        eat(k.octave as u32);
    }
    for d in &f.descriptors {
        eat(d.to_bits());
    }
    (f.keypoints.len(), hash)
}

#[test]
fn sift_matches_the_unpatched_release_bit_for_bit() {
    let native = fingerprint(FirstOctave::Native);
    let double = fingerprint(FirstOctave::Double);
    println!("native {native:?}, double {double:?}");
    assert!(
        native.0 > 20 && double.0 > native.0,
        "{native:?} {double:?}"
    );
    assert_eq!(native, (NATIVE_COUNT, NATIVE_HASH));
    assert_eq!(double, (DOUBLE_COUNT, DOUBLE_HASH));
}

// From the crates.io kornia-imgproc 0.2.0, without the patch (x86-64, AVX2 + FMA build).
const NATIVE_COUNT: usize = 34;
const NATIVE_HASH: u64 = 15_849_276_669_608_691_751;
const DOUBLE_COUNT: usize = 43;
const DOUBLE_HASH: u64 = 1_230_992_068_659_215_704;
