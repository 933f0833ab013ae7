//! The pruned-against-exact table: each MHI rendered within a budget (--budget and any of
//! --also-budgets) and exactly, per view; and the figure of speed-up against PSNR change per
//! budget.

use super::*;

/// One pruned render against the exact render of the same MHI and view.
#[derive(Serialize)]
pub(super) struct PruneMeasure {
    method: String,
    normals: usize,
    planes: usize,
    /// The pruned render's budget, in 8-bit levels (the `bound` is in colour units).
    budget_levels: f32,
    /// Largest |pruned − exact| over pixels and channels (colour units).
    max_abs: f32,
    /// Mean |pruned − exact|.
    mean_abs: f64,
    /// Pixels whose change exceeds the bound the render reported (must be 0).
    over_bound: usize,
    /// Covered PSNR against the ground truth, pruned and exact (None without covered pixels).
    psnr_pruned: Option<f64>,
    psnr_exact: Option<f64>,
    ms_pruned: f64,
    ms_exact: f64,
    layers: usize,
    layers_pruned: usize,
    normals_pruned: usize,
    /// Share of the (tile, layer) pairs the pruned render composited.
    composited: f32,
    /// Share of the (pixel, layer) samples it composited, and the least share any render
    /// within the budget must.
    samples: f32,
    needed: f32,
    bound: f32,
}

impl PruneMeasure {
    pub(super) fn new(
        o: &Output,
        e: &ExactCheck,
        pruned: &Rgb32FImage,
        gt: &Rgb32FImage,
        covered: &[bool],
    ) -> anyhow::Result<Self> {
        let exact = clipped(&e.image);
        let other;
        let (pruned, render_ms) = match &e.pruned {
            Some((image, ms)) => {
                other = clipped(image);
                (&other, *ms)
            }
            None => (pruned, o.times.render_ms),
        };
        let (mut max_abs, mut sum, mut over) = (0.0_f32, 0.0_f64, 0usize);
        for (p, q) in pruned.pixels().zip(exact.pixels()) {
            let d = (0..3)
                .map(|c| (p.0[c] - q.0[c]).abs())
                .fold(0.0_f32, f32::max);
            max_abs = max_abs.max(d);
            sum += (0..3)
                .map(|c| f64::from((p.0[c] - q.0[c]).abs()))
                .sum::<f64>();
            if d > e.stats.bound + 1e-5 {
                over += 1;
            }
        }
        Ok(Self {
            method: o.method.clone(),
            normals: o.normals,
            planes: o.planes,
            budget_levels: e.budget,
            max_abs,
            mean_abs: sum / (3 * pruned.width() as usize * pruned.height() as usize).max(1) as f64,
            over_bound: over,
            psnr_pruned: crate::psnr_masked(pruned, gt, covered)?,
            psnr_exact: crate::psnr_masked(&exact, gt, covered)?,
            ms_pruned: render_ms + o.times.blend_ms,
            ms_exact: e.render_ms + o.times.blend_ms,
            layers: e.stats.layers,
            layers_pruned: e.stats.layers_pruned,
            normals_pruned: e.stats.normals_pruned,
            composited: e.stats.composited,
            samples: e.stats.samples,
            needed: e.needed,
            bound: e.stats.bound,
        })
    }
}

/// Pruned against exact, per method and configuration over every triplet.
#[derive(Serialize)]
pub(super) struct PruneRow {
    pub(super) method: String,
    pub(super) normals: usize,
    pub(super) planes: usize,
    /// The budget, in 8-bit levels (the `bound` is in colour units).
    pub(super) budget_levels: f32,
    pub(super) views: usize,
    pub(super) max_abs: f32,
    pub(super) mean_abs: f64,
    pub(super) over_bound: usize,
    pub(super) bound: f32,
    pub(super) psnr_pruned: f64,
    pub(super) psnr_exact: f64,
    /// Mean covered-PSNR change (pruned − exact) with its 95 % interval (None when a PSNR is
    /// infinite: identical images).
    pub(super) delta_psnr: Option<(f64, [f64; 2])>,
    pub(super) ms_pruned: f64,
    pub(super) ms_exact: f64,
    /// Total exact render time over total pruned render time, and its 95 % bootstrap interval
    /// over views.
    pub(super) speedup: f64,
    pub(super) speedup_ci: Option<[f64; 2]>,
    pub(super) layers: usize,
    pub(super) layers_pruned: f64,
    pub(super) normals_pruned: f64,
    /// Mean share of the (tile, layer) pairs composited.
    pub(super) composited: f64,
    /// Mean share of the samples composited, and the least mean share any render within the
    /// budget must composite.
    pub(super) samples: f64,
    pub(super) needed: f64,
}

pub(super) fn prune_rows(ms_: &[PruneMeasure], boot: &Bootstrap) -> Vec<PruneRow> {
    // Budgets in increasing order within each method and configuration.
    let mut keys: Vec<(String, usize, usize, f32)> = Vec::new();
    for m in ms_ {
        let k = (m.method.clone(), m.normals, m.planes, m.budget_levels);
        if !keys.contains(&k) {
            keys.push(k);
        }
    }
    let first = |k: &(String, usize, usize, f32)| {
        keys.iter()
            .position(|q| (&q.0, q.1, q.2) == (&k.0, k.1, k.2))
            .unwrap_or(0)
    };
    let mut order: Vec<(usize, (String, usize, usize, f32))> =
        keys.iter().map(|k| (first(k), k.clone())).collect();
    order.sort_by(|a, b| a.0.cmp(&b.0).then(a.1.3.total_cmp(&b.1.3)));
    order
        .into_iter()
        .map(|(_, (method, normals, planes, budget))| {
            let g: Vec<&PruneMeasure> = ms_
                .iter()
                .filter(|m| {
                    (m.method.as_str(), m.normals, m.planes, m.budget_levels)
                        == (method.as_str(), normals, planes, budget)
                })
                .collect();
            let k = g.len().max(1) as f64;
            let mean = |f: &dyn Fn(&PruneMeasure) -> f64| g.iter().map(|m| f(m)).sum::<f64>() / k;
            let pairs: Vec<(f64, f64)> = g
                .iter()
                .filter_map(|m| Some((m.psnr_pruned?, m.psnr_exact?)))
                .filter(|(p, e)| p.is_finite() && e.is_finite())
                .collect();
            let deltas: Vec<f64> = pairs.iter().map(|(p, e)| p - e).collect();
            let kp = pairs.len().max(1) as f64;
            let (ms_pruned, ms_exact) = (mean(&|m| m.ms_pruned), mean(&|m| m.ms_exact));
            PruneRow {
                views: g.len(),
                max_abs: g.iter().map(|m| m.max_abs).fold(0.0, f32::max),
                mean_abs: mean(&|m| m.mean_abs),
                over_bound: g.iter().map(|m| m.over_bound).sum(),
                bound: g.iter().map(|m| m.bound).fold(0.0, f32::max),
                psnr_pruned: pairs.iter().map(|p| p.0).sum::<f64>() / kp,
                psnr_exact: pairs.iter().map(|p| p.1).sum::<f64>() / kp,
                delta_psnr: boot.mean_ci(&deltas),
                ms_pruned,
                ms_exact,
                speedup: ms_exact / ms_pruned.max(1e-9),
                speedup_ci: boot
                    .ratio_ci(
                        &g.iter().map(|m| m.ms_exact).collect::<Vec<_>>(),
                        &g.iter().map(|m| m.ms_pruned).collect::<Vec<_>>(),
                    )
                    .map(|(_, ci)| ci),
                layers: g.first().map_or(0, |m| m.layers),
                layers_pruned: mean(&|m| m.layers_pruned as f64),
                normals_pruned: mean(&|m| m.normals_pruned as f64),
                composited: mean(&|m| f64::from(m.composited)),
                samples: mean(&|m| f64::from(m.samples)),
                needed: mean(&|m| f64::from(m.needed)),
                method,
                normals,
                planes,
                budget_levels: budget,
            }
        })
        .collect()
}

pub(super) fn prune_markdown(rows: &[PruneRow], a: &EvalArgs) -> String {
    let mut s = String::from(
        "## Leaving out what a view does not need: pruned against exact

",
    );
    if rows.is_empty() {
        s += if a.exact {
            "Not measured: this report was made with `--exact` (every render exact).\n\n"
        } else {
            "Not measured: no method here renders an MHI with Soft blending.\n\n"
        };
        return s;
    }
    let _ = writeln!(
        s,
        "Every MHI below was rendered both ways per view, exactly and within the error budget of its row, in 8-bit levels per pixel (--budget, by default 1: what the report's other tables score, {}; `--also-budgets` adds rows of other budgets, measured the same way). |Δ| compares the two renders (not the ground truth); ΔPSNR is the change of covered PSNR against the ground truth (mean, 95 % interval); time is the render (and Soft blend) alone, the median of {} renders each way per view, exact and pruned alternating (so that the shared machine's swings hit both alike), and the speed-up the ratio of the mean times (95 % interval, views resampled); layers and normals are those left out of the whole view, \"composited\" the share of (tile of 32 x 8 pixels, layer) pairs the pruned render still composited (it skips layers tile by tile where they are faint or hidden), \"samples\" the share of (pixel, layer) samples it composited (the transmittance stop skips more within a tile) and \"least possible\" the share an ideal plan that knew every pixel's exact contributions would still have to composite within the same budget (`mhi_render::needed_share`: every row is a Soft render, whose weights are known before it and which bounds the blended image alone, so a normal leaves out more where its weight is light; the learned blend's weights come after the render, so its multi-normal images are each bounded on their own, a higher floor, `mhi_render::needed_share_per_normal`): its inverse is the most any leaving-out could speed the view up.\n",
        if a.exact {
            "here `--exact`".to_string()
        } else {
            format!("here {}", a.budget)
        },
        super::methods::PAIRED_RUNS
    );
    s += "| method | budget (levels) | views | max \\|Δ\\| | mean \\|Δ\\| | bound | pixels over bound | ΔPSNR dB | exact ms | pruned ms | speed-up | layers left out | normals left out | composited | samples | least possible |\n|---|---:|---:|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|\n";
    for r in rows {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.5} | {:.6} | {:.5} | {} | {} | {:.1} | {:.1} | {} | {:.1} of {} | {:.2} of {} | {:.0} % | {:.0} % | {:.0} % (≤ {:.2}x) |",
            config_label(&r.method, r.normals, r.planes),
            r.budget_levels,
            r.views,
            r.max_abs,
            r.mean_abs,
            r.bound,
            r.over_bound,
            r.delta_psnr.map_or("-".into(), |(m, [lo, hi])| format!(
                "{m:+.3} [{lo:+.3}, {hi:+.3}]"
            )),
            r.ms_exact,
            r.ms_pruned,
            match r.speedup_ci {
                Some([lo, hi]) => format!("{:.2}x [{lo:.2}, {hi:.2}]", r.speedup),
                None => format!("{:.2}x", r.speedup),
            },
            r.layers_pruned,
            r.layers,
            r.normals_pruned,
            r.normals,
            100.0 * r.composited,
            100.0 * r.samples,
            100.0 * r.needed,
            1.0 / r.needed.max(1e-9)
        );
    }
    s.push('\n');
    if !a.also_budgets.is_empty() {
        s += "![speed-up against PSNR change per budget](budget_tradeoff.svg)\n\nWhat each budget buys and costs: per MHI, the speed-up over its exact render against the change of covered PSNR (means of the rows above), from the exact render (1x, 0 dB) through each budget in increasing order. PNG: [budget_tradeoff.png](budget_tradeoff.png).\n\n";
    }
    s
}

/// `stem.svg` and `.png`: per MHI of the pruned-against-exact table, the speed-up over the
/// exact render against the change of covered PSNR, one point per budget (in increasing order
/// along each line, from the exact render at 1x and 0 dB).
pub(super) fn budget_tradeoff(
    stem: &Path,
    rows: &[PruneRow],
    budgets: &[f32],
) -> anyhow::Result<()> {
    let mut curves: Vec<Curve> = Vec::new();
    for r in rows {
        let label = config_label(&r.method, r.normals, r.planes);
        let Some((delta, _)) = r.delta_psnr else {
            continue;
        };
        match curves.iter_mut().find(|c| c.label == label) {
            Some(c) => c.points.push((r.speedup, delta)),
            // Each line starts at the exact render: 1x, no change.
            None => curves.push(Curve {
                label,
                points: vec![(1.0, 0.0), (r.speedup, delta)],
            }),
        }
    }
    if curves.is_empty() {
        return Ok(());
    }
    let list: Vec<String> = budgets.iter().map(|b| format!("{b}")).collect();
    crate::plot::lines(
        stem,
        &curves,
        &format!(
            "what each budget buys (exact, then {} 8-bit levels)",
            list.join(", ")
        ),
        &crate::plot::Axes {
            x: "speed-up over the exact render (x)",
            y: "covered PSNR change against exact (dB)",
            log: false,
        },
    )?;
    Ok(())
}
