//! How close estimated poses come to known ones, scored as pose-estimation papers do: the
//! rotation error, the angle of the translation direction, and the area under the recall curve
//! of the larger of the two (SuperGlue's AUC), failures counted as infinite errors.

use mhi_geom::RigidTransform;

/// One pair's errors (degrees) and time, or a failure.
#[derive(Debug, Clone, Copy)]
pub struct Outcome {
    /// The angle of the rotation between the estimate and the truth.
    pub rotation_deg: f64,
    /// The angle between the estimated and the true translation directions.
    pub direction_deg: f64,
    /// Wall-clock time of the estimate.
    pub seconds: f64,
    /// No estimate (infinite errors).
    pub failed: bool,
}

impl Outcome {
    /// The errors of the relative pose `(r, t)` (second camera from first) against `truth`.
    pub fn of(r: glam::DMat3, t: glam::DVec3, truth: &RigidTransform, seconds: f64) -> Self {
        let rotation_deg = mhi_geom::rotation_angle_deg(&(r * truth.rotation().transpose()));
        let direction_deg = t
            .normalize()
            .dot(truth.translation().normalize())
            .clamp(-1.0, 1.0)
            .acos()
            .to_degrees();
        Self {
            rotation_deg,
            direction_deg,
            seconds,
            failed: !(rotation_deg.is_finite() && direction_deg.is_finite()),
        }
    }
    /// A pair with no estimate, after `seconds`.
    pub fn failure(seconds: f64) -> Self {
        Self {
            rotation_deg: f64::INFINITY,
            direction_deg: f64::INFINITY,
            seconds,
            failed: true,
        }
    }
}

/// Area under the recall curve of max(rotation, direction) error up to `limit` degrees,
/// normalised to 1 (SuperGlue's pose AUC); failures count as infinite errors.
pub fn auc(errors: &[f64], limit: f64) -> f64 {
    let mut e: Vec<f64> = errors.to_vec();
    e.sort_by(f64::total_cmp);
    let n = e.len() as f64;
    let (mut area, mut last_e, mut last_r) = (0.0, 0.0, 0.0);
    for (i, &x) in e.iter().enumerate() {
        if x > limit {
            break;
        }
        area += (x - last_e) * last_r;
        last_e = x;
        last_r = (i + 1) as f64 / n;
    }
    area += (limit - last_e) * last_r;
    area / limit
}

/// The median of the finite values (NaN when there is none).
pub fn median(v: &[f64]) -> f64 {
    let mut v: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// A markdown table row: pairs, median rotation and direction errors, AUC at 5°, 10° and 20°,
/// failures and the median time per pair.
pub fn table_row(name: &str, o: &[Outcome]) -> String {
    let worst: Vec<f64> = o
        .iter()
        .map(|o| o.rotation_deg.max(o.direction_deg))
        .collect();
    // A median over no finite value (no pair, or every pair failed) is shown as a dash.
    let shown = |x: f64, unit: &str| {
        if x.is_finite() {
            format!("{x:.2}{unit}")
        } else {
            "—".to_string()
        }
    };
    let med = |f: fn(&Outcome) -> f64| median(&o.iter().map(f).collect::<Vec<_>>());
    format!(
        "| {name} | {} | {} | {} | {:.2} / {:.2} / {:.2} | {} | {} |",
        o.len(),
        shown(med(|o| o.rotation_deg), "°"),
        shown(med(|o| o.direction_deg), "°"),
        auc(&worst, 5.0),
        auc(&worst, 10.0),
        auc(&worst, 20.0),
        o.iter().filter(|o| o.failed).count(),
        shown(med(|o| o.seconds), " s"),
    )
}

/// A markdown table row comparing two methods on the pairs both solved (the medians of
/// [`table_row`] are over each method's own successes, so a method that gives up on the hard
/// pairs looks better there): the count, then the median rotation and direction errors of `a`
/// and `b` on those pairs.
pub fn both_solved_row(name: &str, a: &[Outcome], b: &[Outcome]) -> String {
    let (x, y): (Vec<Outcome>, Vec<Outcome>) = a
        .iter()
        .zip(b)
        .filter(|(x, y)| !x.failed && !y.failed)
        .map(|(x, y)| (*x, *y))
        .unzip();
    let med = |o: &[Outcome], f: fn(&Outcome) -> f64| {
        let m = median(&o.iter().map(f).collect::<Vec<_>>());
        if m.is_finite() {
            format!("{m:.2}°")
        } else {
            "—".to_string()
        }
    };
    format!(
        "| {name} | {} | {} / {} | {} / {} |",
        x.len(),
        med(&x, |o| o.rotation_deg),
        med(&y, |o| o.rotation_deg),
        med(&x, |o| o.direction_deg),
        med(&y, |o| o.direction_deg),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn auc_of_known_errors() {
        // Errors 0 and 2 of four pairs (two failures): the recall is 1/4 from 0 to 2 and 1/2 from
        // 2 to 5 → (2·¼ + 3·½)/5 = 0.4.
        let e = [0.0, 2.0, f64::INFINITY, f64::INFINITY];
        assert!((auc(&e, 5.0) - 0.4).abs() < 1e-12);
        assert_eq!(auc(&[f64::INFINITY], 5.0), 0.0);
        assert!((auc(&[0.0], 5.0) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn an_exact_estimate_has_zero_error_and_a_flipped_one_180() {
        let truth = RigidTransform::new(
            glam::DMat3::from_rotation_y(0.1),
            glam::DVec3::new(1.0, 0.0, 0.2),
        )
        .unwrap();
        let o = Outcome::of(truth.rotation(), truth.translation() * 3.0, &truth, 0.1);
        assert!(o.rotation_deg < 1e-6 && o.direction_deg < 1e-6 && !o.failed);
        let f = Outcome::of(truth.rotation(), -truth.translation(), &truth, 0.1);
        assert!((f.direction_deg - 180.0).abs() < 1e-6);
    }

    #[test]
    fn both_solved_compares_only_the_pairs_neither_failed() {
        let truth = RigidTransform::new(glam::DMat3::IDENTITY, glam::DVec3::X).unwrap();
        let tilted = |deg: f64| {
            Outcome::of(
                glam::DMat3::from_rotation_y(deg.to_radians()),
                glam::DVec3::X,
                &truth,
                0.1,
            )
        };
        // `a` solves all three (1°, 2°, 30°); `b` fails the third and solves the others at 3°.
        let a = [tilted(1.0), tilted(2.0), tilted(30.0)];
        let b = [tilted(3.0), tilted(3.0), Outcome::failure(0.1)];
        assert_eq!(
            both_solved_row("s (5)", &a, &b),
            "| s (5) | 2 | 2.00° / 3.00° | 0.00° / 0.00° |"
        );
        assert_eq!(
            both_solved_row("s (5)", &[Outcome::failure(0.1)], &b[..1]),
            "| s (5) | 0 | — / — | — / — |"
        );
    }

    #[test]
    fn rows_show_a_dash_where_there_is_no_median() {
        let truth = RigidTransform::new(glam::DMat3::IDENTITY, glam::DVec3::X).unwrap();
        let good = Outcome::of(glam::DMat3::IDENTITY, glam::DVec3::X, &truth, 0.25);
        assert_eq!(
            table_row("set (5), ours", &[good, Outcome::failure(0.5)]),
            "| set (5), ours | 2 | 0.00° | 0.00° | 0.50 / 0.50 / 0.50 | 1 | 0.50 s |"
        );
        assert_eq!(
            table_row("set (5), ours", &[Outcome::failure(0.5)]),
            "| set (5), ours | 1 | — | — | 0.00 / 0.00 / 0.00 | 1 | 0.50 s |"
        );
        assert_eq!(
            table_row("none", &[]),
            "| none | 0 | — | — | 0.00 / 0.00 / 0.00 | 0 | — |"
        );
    }
}
