//! `cargo xtask stability`: the f32 pipeline against the f64 reference on stiff and extreme
//! cases, as a table (and JSON); exits non-zero if any case fails.

use std::path::PathBuf;

use anyhow::bail;
use clap::Args;
use mhi_render::stability::{MAX_ABS_ERROR, stability_case_count, stability_table};

/// Options of `cargo xtask stability`.
#[derive(Args, Debug)]
pub struct StabilityArgs {
    /// Also write the table as JSON to this file.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

/// `cargo xtask stability`.
pub fn stability(a: &StabilityArgs) -> anyhow::Result<()> {
    let pb = crate::progress::bar(stability_case_count() as u64, "cases");
    let rows = stability_table(&|_| pb.inc(1))?;
    pb.finish_and_clear();
    println!(
        "{:<26}{:>11}{:>6}{:>6}{:>12}{:>12}{:>9}{:>8}{:>10}{:>6}",
        "case",
        "size",
        "N",
        "D",
        "max |err|",
        "mean |err|",
        "NaN/Inf",
        "masked",
        "detected",
        "pass"
    );
    for r in &rows {
        println!(
            "{:<26}{:>11}{:>6}{:>6}{:>12.2e}{:>12.2e}{:>9}{:>8}{:>10}{:>6}",
            r.case,
            format!("{}x{}", r.size[0], r.size[1]),
            r.normals,
            r.planes,
            r.max_abs_error,
            r.mean_abs_error,
            r.non_finite,
            r.layers_masked,
            if r.degenerate {
                if r.detected { "yes" } else { "NO" }
            } else {
                "-"
            },
            if r.pass { "ok" } else { "FAIL" }
        );
    }
    println!("bound: max |f32 − f64| ≤ {MAX_ABS_ERROR:e}, no NaN/Inf, degenerate cases masked");
    if let Some(p) = &a.json {
        mhi_data::write_atomic(p, &serde_json::to_vec_pretty(&rows)?)?;
        println!("wrote {}", p.display());
    }
    let failed: Vec<&str> = rows
        .iter()
        .filter(|r| !r.pass)
        .map(|r| r.case.as_str())
        .collect();
    if !failed.is_empty() {
        bail!(
            "{} stability case(s) failed: {}",
            failed.len(),
            failed.join(", ")
        );
    }
    Ok(())
}
