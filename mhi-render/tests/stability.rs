//! The stability table stays true: no NaN/Inf, f32 within the bound of the f64 reference, and
//! degenerate geometry detected and masked, on every extreme case.

use mhi_render::stability::{MAX_ABS_ERROR, stability_case_count, stability_table};

#[test]
fn every_extreme_case_is_finite_accurate_and_masked() {
    let rows = stability_table(&|_| {}).unwrap();
    assert_eq!(rows.len(), stability_case_count());
    assert!(rows.len() >= 25, "the table lost cases: {}", rows.len());
    for r in &rows {
        assert_eq!(
            r.non_finite, 0,
            "{}: {} non-finite values",
            r.case, r.non_finite
        );
        assert!(
            r.max_abs_error <= MAX_ABS_ERROR,
            "{}: max |f32 − f64| = {:e}",
            r.case,
            r.max_abs_error
        );
        assert!(r.detected, "{}: degenerate geometry not masked", r.case);
    }
    // The degenerate cases really are degenerate: something was masked in them.
    assert!(
        rows.iter()
            .filter(|r| r.degenerate)
            .all(|r| r.layers_masked > 0),
        "{rows:#?}"
    );
}
