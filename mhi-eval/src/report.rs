//! The evaluation report: per-view measurements, their aggregation into rows (method × (N, D) ×
//! rotation bin × interpolation/extrapolation), and the tables of `report.md`, `report.json`
//! and `report.csv`. Every number in the tables is computed here from the rows.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use serde::{Deserialize, Serialize};

/// Rotation-bin labels in table order; `"all"` pools every bin.
pub const BINS: [&str; 5] = ["0-2", "2-4", "4-8", ">8", "all"];
/// Triplet kinds in table order; `"all"` pools both.
pub const KINDS: [&str; 3] = ["interpolation", "extrapolation", "all"];

/// Wall-clock split of producing one novel view, in milliseconds.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Times {
    /// Cost volume (plane sweep of the source view) or the training-free sweep MHI.
    pub volume_ms: f64,
    /// Stage-1 network (alphas).
    pub network_ms: f64,
    /// Warping and compositing the N multi-normal images.
    pub render_ms: f64,
    /// Blending the multi-normal images (weights and their sum).
    pub blend_ms: f64,
}

impl Times {
    /// Total milliseconds.
    pub fn total(&self) -> f64 {
        self.volume_ms + self.network_ms + self.render_ms + self.blend_ms
    }
}

/// One scored novel view of one method.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Measurement {
    /// Method name (`learned`, `soft`, `hard`, `avg`, `mpi`, `sweep`, `oracle`, `nearest`).
    pub method: String,
    /// Normals N (0 for `nearest`).
    pub normals: usize,
    /// Planes per normal D (0 for `nearest`).
    pub planes: usize,
    /// Sequence of the triplet.
    pub sequence: String,
    /// Frame index of the target view.
    pub target: usize,
    /// Rotation bin label (one of the first four of [`BINS`]).
    pub bin: String,
    /// `interpolation` or `extrapolation`.
    pub kind: String,
    /// PSNR (dB) of the image clipped to [0, 1].
    pub psnr: f64,
    /// SSIM.
    pub ssim: f64,
    /// LPIPS-alex v0.1, when the weights are available.
    pub lpips: Option<f64>,
    /// Time split.
    pub times: Times,
}

/// One aggregated row of the report.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Row {
    /// Method name.
    pub method: String,
    /// Normals N.
    pub normals: usize,
    /// Planes per normal D.
    pub planes: usize,
    /// Rotation bin (see [`BINS`]).
    pub bin: String,
    /// Triplet kind (see [`KINDS`]).
    pub kind: String,
    /// Views averaged.
    pub count: usize,
    /// Mean PSNR (dB).
    pub psnr: f64,
    /// Mean SSIM.
    pub ssim: f64,
    /// Mean LPIPS-alex (absent without weights).
    pub lpips: Option<f64>,
    /// Mean milliseconds per novel view (sum of the split below).
    pub ms_per_view: f64,
    /// Mean time split.
    pub times: Times,
}

/// Aggregate measurements into rows: for every method and (N, D), every bin including `all`
/// and every kind including `all`; groups with no view are left out. Methods keep the order of
/// their first measurement.
pub fn aggregate(ms: &[Measurement]) -> Vec<Row> {
    let mut order: Vec<(String, usize, usize)> = Vec::new();
    let mut groups: BTreeMap<(usize, usize, usize), Vec<&Measurement>> = BTreeMap::new();
    for m in ms {
        let key = (m.method.clone(), m.normals, m.planes);
        let k = match order.iter().position(|o| *o == key) {
            Some(k) => k,
            None => {
                order.push(key);
                order.len() - 1
            }
        };
        let bins = [BINS.iter().position(|b| *b == m.bin).unwrap_or(4), 4];
        let kinds = [KINDS.iter().position(|b| *b == m.kind).unwrap_or(2), 2];
        for (bi, b) in bins.iter().enumerate() {
            if bi == 1 && *b == bins[0] {
                continue;
            }
            for (ki, kk) in kinds.iter().enumerate() {
                if ki == 1 && *kk == kinds[0] {
                    continue;
                }
                groups.entry((k, *b, *kk)).or_default().push(m);
            }
        }
    }
    groups
        .into_iter()
        .map(|((k, b, kk), v)| {
            let n = v.len() as f64;
            let mean = |f: &dyn Fn(&Measurement) -> f64| v.iter().map(|m| f(m)).sum::<f64>() / n;
            let lpips = if v.iter().all(|m| m.lpips.is_some()) {
                Some(mean(&|m| m.lpips.unwrap_or(0.0)))
            } else {
                None
            };
            let times = Times {
                volume_ms: mean(&|m| m.times.volume_ms),
                network_ms: mean(&|m| m.times.network_ms),
                render_ms: mean(&|m| m.times.render_ms),
                blend_ms: mean(&|m| m.times.blend_ms),
            };
            Row {
                method: order[k].0.clone(),
                normals: order[k].1,
                planes: order[k].2,
                bin: BINS[b].into(),
                kind: KINDS[kk].into(),
                count: v.len(),
                psnr: mean(&|m| m.psnr),
                ssim: mean(&|m| m.ssim),
                lpips,
                ms_per_view: times.total(),
                times,
            }
        })
        .collect()
}

/// `report.csv`: one line per row.
pub fn csv(rows: &[Row]) -> String {
    let mut s = String::from(
        "method,normals,planes,bin,kind,count,psnr,ssim,lpips,ms_per_view,volume_ms,network_ms,render_ms,blend_ms\n",
    );
    for r in rows {
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{:.4},{:.5},{},{:.3},{:.3},{:.3},{:.3},{:.3}",
            r.method,
            r.normals,
            r.planes,
            r.bin,
            r.kind,
            r.count,
            r.psnr,
            r.ssim,
            r.lpips.map_or(String::new(), |l| format!("{l:.5}")),
            r.ms_per_view,
            r.times.volume_ms,
            r.times.network_ms,
            r.times.render_ms,
            r.times.blend_ms
        );
    }
    s
}

/// A method and configuration: `learned N=5 D=8`.
pub fn config_label(method: &str, normals: usize, planes: usize) -> String {
    if normals == 0 {
        method.to_string()
    } else {
        format!("{method} N={normals} D={planes}")
    }
}

fn find<'a>(rows: &'a [Row], key: (&str, usize, usize), bin: &str, kind: &str) -> Option<&'a Row> {
    rows.iter().find(|r| {
        r.method == key.0
            && r.normals == key.1
            && r.planes == key.2
            && r.bin == bin
            && r.kind == kind
    })
}

/// The configurations of the rows, in row order.
pub fn configs(rows: &[Row]) -> Vec<(String, usize, usize)> {
    let mut out: Vec<(String, usize, usize)> = Vec::new();
    for r in rows {
        let k = (r.method.clone(), r.normals, r.planes);
        if !out.contains(&k) {
            out.push(k);
        }
    }
    out
}

/// The tables of `report.md`: each metric per method × rotation bin (all kinds), then
/// interpolation vs extrapolation, the N × D sweep of every method run at several
/// configurations, and the time split.
pub fn markdown_tables(rows: &[Row]) -> String {
    let mut s = String::new();
    let cfgs = configs(rows);
    let bins_present: Vec<&str> = BINS
        .iter()
        .copied()
        .filter(|b| rows.iter().any(|r| r.bin == *b))
        .collect();
    type Metric = (&'static str, fn(&Row) -> Option<f64>, usize);
    let metrics: [Metric; 3] = [
        ("PSNR (dB, higher is better)", |r| Some(r.psnr), 2),
        ("SSIM (higher is better)", |r| Some(r.ssim), 3),
        ("LPIPS-alex (lower is better)", |r| r.lpips, 3),
    ];
    for (title, get, prec) in metrics {
        if !rows.iter().any(|r| get(r).is_some()) {
            let _ = writeln!(
                s,
                "### {title}\n\nnot computed: the LPIPS weights are not in the cache (`cargo xtask weights`).\n"
            );
            continue;
        }
        let _ = writeln!(s, "### {title} by rotation bin\n");
        let _ = write!(s, "| method |");
        for b in &bins_present {
            let n = rows
                .iter()
                .find(|r| r.bin == *b && r.kind == "all")
                .map_or(0, |r| r.count);
            let unit = if *b == "all" { "" } else { "°" };
            let _ = write!(s, " {b}{unit} (n={n}) |");
        }
        let _ = writeln!(s, " ms/view |");
        let _ = writeln!(s, "|---|{}---:|", "---:|".repeat(bins_present.len()));
        for (m, n, d) in &cfgs {
            let _ = write!(s, "| {} |", config_label(m, *n, *d));
            for b in &bins_present {
                match find(rows, (m, *n, *d), b, "all").and_then(get) {
                    Some(v) => {
                        let _ = write!(s, " {v:.prec$} |");
                    }
                    None => s.push_str(" – |"),
                }
            }
            let ms = find(rows, (m, *n, *d), "all", "all").map_or(0.0, |r| r.ms_per_view);
            let _ = writeln!(s, " {ms:.1} |");
        }
        s.push('\n');
    }
    let _ = writeln!(s, "### Interpolation and extrapolation (all bins)\n");
    let _ = writeln!(
        s,
        "| method | interp. PSNR | interp. SSIM | extrap. PSNR | extrap. SSIM |\n|---|---:|---:|---:|---:|"
    );
    for (m, n, d) in &cfgs {
        let cell = |kind: &str| {
            find(rows, (m, *n, *d), "all", kind).map_or(" – | – |".to_string(), |r| {
                format!(" {:.2} | {:.3} |", r.psnr, r.ssim)
            })
        };
        let _ = writeln!(
            s,
            "| {} |{}{}",
            config_label(m, *n, *d),
            cell("interpolation"),
            cell("extrapolation")
        );
    }
    s.push('\n');
    // N × D sweep: methods evaluated at more than one configuration.
    let mut methods: Vec<&str> = Vec::new();
    for (m, _, _) in &cfgs {
        if !methods.contains(&m.as_str()) {
            methods.push(m);
        }
    }
    for m in methods {
        let mine: Vec<&(String, usize, usize)> = cfgs.iter().filter(|c| c.0 == m).collect();
        if mine.len() < 2 {
            continue;
        }
        let mut ns: Vec<usize> = mine.iter().map(|c| c.1).collect();
        let mut ds: Vec<usize> = mine.iter().map(|c| c.2).collect();
        ns.sort_unstable();
        ns.dedup();
        ds.sort_unstable();
        ds.dedup();
        let _ = writeln!(
            s,
            "### N × D sweep: {m} (PSNR dB / ms per view, all triplets)\n"
        );
        let _ = write!(s, "| N \\ D |");
        for d in &ds {
            let _ = write!(s, " D={d} |");
        }
        let _ = writeln!(s, "\n|---|{}", "---:|".repeat(ds.len()));
        for n in &ns {
            let _ = write!(s, "| N={n} |");
            for d in &ds {
                match find(rows, (m, *n, *d), "all", "all") {
                    Some(r) => {
                        let _ = write!(s, " {:.2} / {:.1} |", r.psnr, r.ms_per_view);
                    }
                    None => s.push_str(" – |"),
                }
            }
            s.push('\n');
        }
        s.push('\n');
    }
    let _ = writeln!(
        s,
        "### Time per novel view (ms, mean over all triplets)\n\n| method | cost volume | network | render | blend | total |\n|---|---:|---:|---:|---:|---:|"
    );
    for (m, n, d) in &cfgs {
        if let Some(r) = find(rows, (m, *n, *d), "all", "all") {
            let t = r.times;
            let _ = writeln!(
                s,
                "| {} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} |",
                config_label(m, *n, *d),
                t.volume_ms,
                t.network_ms,
                t.render_ms,
                t.blend_ms,
                r.ms_per_view
            );
        }
    }
    s.push('\n');
    s
}

/// Indices of the points on the Pareto front of (time, quality): no other point is at least as
/// fast and at least as good, and strictly better in one. Sorted by time.
pub fn pareto_front(points: &[(f64, f64)], higher_is_better: bool) -> Vec<usize> {
    let better = |a: f64, b: f64| if higher_is_better { a > b } else { a < b };
    let at_least = |a: f64, b: f64| if higher_is_better { a >= b } else { a <= b };
    let mut front: Vec<usize> = (0..points.len())
        .filter(|&i| {
            let (ti, qi) = points[i];
            ti.is_finite()
                && qi.is_finite()
                && !points.iter().enumerate().any(|(j, &(tj, qj))| {
                    j != i && tj <= ti && at_least(qj, qi) && (tj < ti || better(qj, qi))
                })
        })
        .collect();
    front.sort_by(|&a, &b| points[a].0.total_cmp(&points[b].0));
    front
}

#[cfg(test)]
mod tests {
    use super::*;

    fn m(method: &str, bin: &str, kind: &str, psnr: f64, ms: f64) -> Measurement {
        Measurement {
            method: method.into(),
            normals: 5,
            planes: 8,
            sequence: "s".into(),
            target: 0,
            bin: bin.into(),
            kind: kind.into(),
            psnr,
            ssim: 0.5,
            lpips: Some(0.1),
            times: Times {
                render_ms: ms,
                ..Times::default()
            },
        }
    }

    #[test]
    fn aggregation_pools_bins_and_kinds() {
        let ms = vec![
            m("a", "0-2", "interpolation", 20.0, 1.0),
            m("a", ">8", "extrapolation", 10.0, 3.0),
            m("b", ">8", "interpolation", 30.0, 5.0),
        ];
        let rows = aggregate(&ms);
        let get = |method: &str, bin: &str, kind: &str| {
            rows.iter()
                .find(|r| r.method == method && r.bin == bin && r.kind == kind)
                .cloned()
        };
        let all = get("a", "all", "all").unwrap();
        assert_eq!(all.count, 2);
        assert!((all.psnr - 15.0).abs() < 1e-12);
        assert!((all.ms_per_view - 2.0).abs() < 1e-12);
        assert_eq!(get("a", ">8", "all").unwrap().count, 1);
        assert_eq!(get("a", "all", "interpolation").unwrap().psnr, 20.0);
        assert!(get("a", "2-4", "all").is_none());
        assert_eq!(get("b", "all", "all").unwrap().psnr, 30.0);
        // Methods keep their order; the tables mention both.
        let md = markdown_tables(&rows);
        assert!(md.find("| a N=5 D=8").unwrap() < md.find("| b N=5 D=8").unwrap());
        assert!(csv(&rows).lines().count() == rows.len() + 1);
    }

    #[test]
    fn pareto_front_keeps_only_undominated_points() {
        // (ms, psnr)
        let p = [
            (1.0, 10.0),
            (2.0, 12.0),
            (3.0, 11.0),
            (4.0, 15.0),
            (4.0, 14.0),
        ];
        assert_eq!(pareto_front(&p, true), vec![0, 1, 3]);
        // For an error (lower is better) the same logic mirrors.
        let e = [(1.0, 0.5), (2.0, 0.6), (3.0, 0.2)];
        assert_eq!(pareto_front(&e, false), vec![0, 2]);
        // NaN never joins the front.
        assert_eq!(pareto_front(&[(1.0, f64::NAN), (2.0, 1.0)], true), vec![1]);
    }
}
