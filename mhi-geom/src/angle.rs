//! The angle cost δ between a plane normal and a target pixel's ray (paper Eq. 3) and the
//! heuristic blending weights built from it (Eq. 4).

use glam::{DMat3, DVec3};
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result, ensure_finite};

/// The cosine `δ = |nᵀ r| / (‖n‖ ‖r‖)` between a normal and a ray, both in the same frame, in
/// `[0, 1]`. `1` means the plane faces the ray head-on, `0` that it is seen edge-on.
///
/// Fails on zero-length or non-finite inputs instead of returning NaN.
pub fn angle_cost(normal: DVec3, ray: DVec3) -> Result<f64> {
    ensure_finite("normal", &normal.to_array())?;
    ensure_finite("ray", &ray.to_array())?;
    // Scale by the largest component first so huge or tiny vectors cannot overflow or
    // underflow the norms.
    let unit = |v: DVec3, what| {
        let m = v.abs().max_element();
        if m == 0.0 {
            return Err(Error::ZeroVector { what });
        }
        Ok((v / m).normalize())
    };
    let c = unit(normal, "normal")?.dot(unit(ray, "ray")?).abs();
    // Cauchy–Schwarz can exceed 1 by one rounding step; the true value cannot.
    Ok(c.min(1.0))
}

/// Paper Eq. 3: `δ(n_i, u_t) = |(Rᵀn_i)ᵀ K_t⁻¹u_t| / (‖Rᵀn_i‖ ‖K_t⁻¹u_t‖)` where `R` is the
/// rotation of `ref_from_tgt` (so `Rᵀ n` is the reference-frame normal expressed in the target
/// frame) and `ray_in_tgt = K_t⁻¹ u_t`.
pub fn angle_cost_in_target(
    normal_in_ref: DVec3,
    ref_from_tgt_rotation: &DMat3,
    ray_in_tgt: DVec3,
) -> Result<f64> {
    angle_cost(
        ref_from_tgt_rotation.transpose() * normal_in_ref,
        ray_in_tgt,
    )
}

/// How the multi-normal images are blended when no learned network is used (paper Eq. 4).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum BlendHeuristic {
    /// `ω = 1`: the plain average of the multi-normal images.
    Avg,
    /// One-hot on the normal with the largest δ (the first one on ties).
    Hard,
    /// `ω = exp(3 (2δ − 1))`.
    Soft,
}

impl BlendHeuristic {
    /// Every heuristic, in the paper's order.
    pub const ALL: [Self; 3] = [Self::Avg, Self::Hard, Self::Soft];

    /// Lower-case name, as used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Self::Avg => "avg",
            Self::Hard => "hard",
            Self::Soft => "soft",
        }
    }

    /// Normalised weights (summing to 1) for the angle costs `deltas` of one pixel, written to
    /// `weights` (same length). Entries of `deltas` outside `[0, 1]` are clamped into it.
    ///
    /// # Panics
    /// If the slices differ in length or are empty (a caller bug).
    pub fn weights_into(self, deltas: &[f64], weights: &mut [f64]) {
        assert_eq!(deltas.len(), weights.len(), "one weight per normal");
        assert!(!deltas.is_empty(), "at least one normal");
        match self {
            Self::Avg => weights.fill(1.0),
            Self::Hard => {
                let mut best = 0;
                for (i, d) in deltas.iter().enumerate() {
                    if *d > deltas[best] {
                        best = i;
                    }
                }
                weights.fill(0.0);
                weights[best] = 1.0;
            }
            Self::Soft => {
                for (w, d) in weights.iter_mut().zip(deltas) {
                    *w = soft_weight(*d);
                }
            }
        }
        let sum: f64 = weights.iter().sum();
        for w in weights.iter_mut() {
            *w /= sum;
        }
    }

    /// As [`BlendHeuristic::weights_into`], allocating.
    pub fn weights(self, deltas: &[f64]) -> Vec<f64> {
        let mut w = vec![0.0; deltas.len()];
        self.weights_into(deltas, &mut w);
        w
    }
}

impl std::str::FromStr for BlendHeuristic {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s.to_ascii_lowercase().as_str() {
            "avg" | "average" => Ok(Self::Avg),
            "hard" => Ok(Self::Hard),
            "soft" => Ok(Self::Soft),
            _ => Err(format!(
                "unknown blend heuristic {s:?}; expected avg, hard or soft"
            )),
        }
    }
}

/// The unnormalised soft weight `exp(3 (2δ − 1))`, in `[e⁻³, e³]` for δ clamped to `[0, 1]`
/// (NaN is treated as 0). Branch-free ([`exp_small`]), so that a loop of them vectorises: a
/// renderer computes it for every normal at every pixel of a view.
#[inline]
pub fn soft_weight(delta: f64) -> f64 {
    exp_small(soft_exponent(delta))
}

/// `3 (2δ − 1)` for δ clamped to `[0, 1]`, NaN taken as 0: the exponent of [`soft_weight`].
#[inline]
fn soft_exponent(delta: f64) -> f64 {
    let d = if delta.is_nan() {
        0.0
    } else {
        delta.clamp(0.0, 1.0)
    };
    3.0 * (2.0 * d - 1.0)
}

/// [`soft_weight`] to a relative 2·10⁻¹⁰ instead of the last digits ([`exp_taylor`] to degree
/// 8): enough for weights stored as f32, and a quarter cheaper, for the renderer's weights of
/// every normal at every pixel.
#[inline]
pub fn soft_weight_for_f32(delta: f64) -> f64 {
    exp_taylor::<8>(soft_exponent(delta))
}

/// `1 / n!` for `n = 0 … 12`: the Taylor series of [`exp_taylor`].
const INV_FACTORIAL: [f64; 13] = {
    let mut c = [1.0; 13];
    let mut n = 1;
    while n < 13 {
        c[n] = c[n - 1] / n as f64;
        n += 1;
    }
    c
};

/// `eˣ` for `|x| ≤ 700`, within a few units in the last place of [`f64::exp`] (tested to
/// 1e-15 relative over `[−3, 3]`, where [`soft_weight`] takes it), without a branch or a libm
/// call: [`exp_taylor`] to degree 12 (the next term is below 2·10⁻¹⁶ of it).
#[inline]
pub fn exp_small(x: f64) -> f64 {
    exp_taylor::<12>(x)
}

/// `eˣ` for `|x| ≤ 700` as [`exp_small`] computes it, with the series cut after `rᴰᴱᴳᴿᴱᴱ`:
/// `x = k ln 2 + r` with `k` an integer and `|r| ≤ ln 2 / 2`, `eʳ` by its Taylor series, `2ᵏ`
/// through the exponent bits. The relative error is about `(ln 2 / 2)^(D+1) / (D+1)!`: 2·10⁻¹⁰
/// at degree 8. `DEGREE` is at most 12.
#[inline]
pub fn exp_taylor<const DEGREE: usize>(x: f64) -> f64 {
    const { assert!(DEGREE >= 1 && DEGREE <= 12) };
    // 1.5 · 2⁵²: adding it rounds a float of magnitude below 2⁵¹ to an integer, which is then
    // the low bits of the sum.
    const SHIFT: f64 = 6_755_399_441_055_744.0;
    // ln 2 split so that `k · LN2_HI` is exact for |k| < 2¹¹ (fdlibm's constants, by their
    // bits: 6.93147180369123816490e-01 and 1.90821492927058770002e-10).
    const LN2_HI: f64 = f64::from_bits(0x3fe6_2e42_fee0_0000);
    const LN2_LO: f64 = f64::from_bits(0x3dea_39ef_3579_3c76);
    let x = x.clamp(-700.0, 700.0);
    let t = x * std::f64::consts::LOG2_E + SHIFT;
    let k = t - SHIFT;
    let r = (x - k * LN2_HI) - k * LN2_LO;
    let mut p = INV_FACTORIAL[DEGREE];
    for c in INV_FACTORIAL[..DEGREE].iter().rev() {
        p = p * r + c;
    }
    let k_int = t.to_bits().wrapping_sub(SHIFT.to_bits()) as i64;
    f64::from_bits(((k_int + 1023) << 52) as u64) * p
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::assert_close;
    use proptest::prelude::*;

    #[test]
    fn head_on_and_edge_on() {
        assert_close(
            angle_cost(DVec3::Z, DVec3::new(0.0, 0.0, 3.0)).unwrap(),
            1.0,
            0.0,
        );
        assert_close(
            angle_cost(DVec3::Z, DVec3::new(0.0, 0.0, -3.0)).unwrap(),
            1.0,
            0.0,
        );
        assert_close(
            angle_cost(DVec3::X, DVec3::new(0.0, 1.0, 1.0)).unwrap(),
            0.0,
            0.0,
        );
        // Nearly edge-on: the cosine of 89.9999° is tiny but exact enough and never negative.
        let a = (90.0_f64 - 1e-4).to_radians();
        let ray = DVec3::new(a.cos(), 0.0, a.sin());
        assert_close(
            angle_cost(DVec3::X, ray).unwrap(),
            1e-4_f64.to_radians().sin(),
            1e-15,
        );
    }

    #[test]
    fn degenerate_inputs_are_errors() {
        assert_eq!(
            angle_cost(DVec3::ZERO, DVec3::Z),
            Err(Error::ZeroVector { what: "normal" })
        );
        assert!(angle_cost(DVec3::Z, DVec3::new(f64::NAN, 0.0, 1.0)).is_err());
        // Overflow-prone magnitudes still work.
        assert_close(
            angle_cost(DVec3::Z * 1e300, DVec3::Z * 1e300).unwrap(),
            1.0,
            0.0,
        );
        assert_close(
            angle_cost(DVec3::Z * 1e-300, DVec3::Z * 1e-300).unwrap(),
            1.0,
            1e-15,
        );
    }

    #[test]
    fn rotation_moves_the_normal_into_the_target_frame() {
        // Target camera yawed 90° about y relative to the reference: the reference's fronto
        // normal (0, 0, 1) becomes the target's x axis, so the target's central ray sees it
        // edge-on.
        let r = DMat3::from_rotation_y(std::f64::consts::FRAC_PI_2);
        let d = angle_cost_in_target(DVec3::Z, &r, DVec3::Z).unwrap();
        assert!(d < 1e-15, "{d}");
        let d = angle_cost_in_target(DVec3::Z, &r, DVec3::new(-1.0, 0.0, 0.0)).unwrap();
        assert_close(d, 1.0, 1e-15);
    }

    #[test]
    fn heuristics() {
        let d = [0.2, 0.9, 0.9, 0.1];
        assert_eq!(BlendHeuristic::Hard.weights(&d), vec![0.0, 1.0, 0.0, 0.0]);
        assert_eq!(BlendHeuristic::Avg.weights(&d), vec![0.25; 4]);
        let s = BlendHeuristic::Soft.weights(&d);
        assert_close(s.iter().sum::<f64>(), 1.0, 1e-15);
        assert_close(s[1] / s[0], (3.0 * 2.0 * 0.7_f64).exp(), 1e-12);
        assert_eq!("SOFT".parse::<BlendHeuristic>(), Ok(BlendHeuristic::Soft));
        assert!("median".parse::<BlendHeuristic>().is_err());
    }

    #[test]
    fn exp_small_is_exp_to_the_last_digits() {
        let mut worst = 0.0_f64;
        for i in -300_000..=300_000 {
            let x = f64::from(i) * 1e-5;
            let rel = (exp_small(x) - x.exp()).abs() / x.exp();
            worst = worst.max(rel);
        }
        assert!(worst < 1e-15, "worst relative error {worst:e} over [-3, 3]");
        for x in [-700.0, -100.0, -20.5, 0.0, 1e-300, 20.5, 100.0, 700.0] {
            let rel = (exp_small(x) - f64::exp(x)).abs() / f64::exp(x);
            assert!(rel < 1e-14, "exp_small({x}) off by {rel:e}");
        }
        assert_eq!(exp_small(0.0), 1.0);
    }

    #[test]
    fn the_soft_weight_for_f32_is_the_soft_weight_to_f32_precision() {
        let mut worst = 0.0_f64;
        for i in -10..=100_010 {
            let d = f64::from(i) * 1e-5;
            let rel = (soft_weight_for_f32(d) - soft_weight(d)).abs() / soft_weight(d);
            worst = worst.max(rel);
        }
        assert!(worst < 3e-10, "worst relative error {worst:e}");
        assert_eq!(soft_weight_for_f32(f64::NAN), soft_weight_for_f32(0.0));
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(4096))]

        #[test]
        fn delta_in_unit_interval(n in prop::array::uniform3(-1e3f64..1e3), r in prop::array::uniform3(-1e3f64..1e3)) {
            let (n, r) = (DVec3::from_array(n), DVec3::from_array(r));
            prop_assume!(n.length() > 0.0 && r.length() > 0.0);
            let d = angle_cost(n, r).unwrap();
            prop_assert!((0.0..=1.0).contains(&d), "δ = {}", d);
        }

        #[test]
        fn soft_weights_positive_and_finite(deltas in prop::collection::vec(prop::num::f64::ANY, 1..9)) {
            for d in &deltas {
                let w = soft_weight(*d);
                prop_assert!(w.is_finite() && w > 0.0, "ω({}) = {}", d, w);
            }
            let w = BlendHeuristic::Soft.weights(&deltas);
            prop_assert!(w.iter().all(|w| w.is_finite() && *w > 0.0));
            prop_assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        }
    }
}
