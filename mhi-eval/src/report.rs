//! The evaluation report: per-view measurements, their aggregation into rows (method × (N, D) ×
//! rotation bin × interpolation/extrapolation), and the tables of `report.md`, `report.json`
//! and `report.csv`. Every number in the tables is computed here from the rows.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use mhi_data::RotationBin;
use serde::{Deserialize, Serialize};

use crate::stats::Bootstrap;

/// Rotation-bin keys in table order ([`RotationBin::key`]); `"all"` pools every bin.
pub const BINS: [&str; 5] = [
    RotationBin::UpTo2.key(),
    RotationBin::From2To4.key(),
    RotationBin::From4To8.key(),
    RotationBin::Over8.key(),
    "all",
];

/// The table label of a bin key: the bin's own label (`≤2°`, …), or the key itself (`all`).
pub fn bin_label(key: &str) -> &str {
    match RotationBin::from_key(key) {
        Some(b) => b.label(),
        None => key,
    }
}
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
///
/// Scores come twice: on the whole image (the papers' protocol) and on the *covered* region
/// ([`crate::coverage`]): the target pixels the reference view sees on the farthest plane, one
/// geometric mask per triplet shared by every method.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Measurement {
    /// Index of the triplet in the evaluation (pairs the methods' scores of one view).
    #[serde(default)]
    pub triplet: usize,
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
    /// PSNR over the covered pixels (`None` when no pixel is covered).
    #[serde(default)]
    pub psnr_covered: Option<f64>,
    /// SSIM map averaged over the covered pixels.
    #[serde(default)]
    pub ssim_covered: Option<f64>,
    /// LPIPS-alex of the render with its uncovered pixels replaced by the ground truth's (they
    /// then contribute no difference), when the weights are available.
    #[serde(default)]
    pub lpips_covered: Option<f64>,
    /// Fraction of the target's pixels that are covered.
    #[serde(default)]
    pub covered_fraction: f64,
    /// Time split.
    pub times: Times,
    /// Whether `times` was measured here: `false` for a render made by another program and
    /// scored from its file (`eval --renders`), whose time is unknown (`times` then zero).
    #[serde(default = "yes")]
    pub timed: bool,
}

fn yes() -> bool {
    true
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
    /// Mean PSNR (dB) over the whole image.
    pub psnr: f64,
    /// 95 % bootstrap interval of `psnr` over triplets.
    pub psnr_ci: [f64; 2],
    /// Mean SSIM over the whole image.
    pub ssim: f64,
    /// Interval of `ssim`.
    pub ssim_ci: [f64; 2],
    /// Mean LPIPS-alex over the whole image (absent without weights).
    pub lpips: Option<f64>,
    /// Interval of `lpips`.
    pub lpips_ci: Option<[f64; 2]>,
    /// Mean PSNR over the covered region (views with no covered pixel left out).
    pub psnr_covered: Option<f64>,
    /// Interval of `psnr_covered`.
    pub psnr_covered_ci: Option<[f64; 2]>,
    /// Mean SSIM over the covered region.
    pub ssim_covered: Option<f64>,
    /// Interval of `ssim_covered`.
    pub ssim_covered_ci: Option<[f64; 2]>,
    /// Mean LPIPS-alex with uncovered pixels taken from the ground truth.
    pub lpips_covered: Option<f64>,
    /// Interval of `lpips_covered`.
    pub lpips_covered_ci: Option<[f64; 2]>,
    /// Mean fraction of covered pixels.
    pub covered_fraction: f64,
    /// Views with at least one covered pixel: the covered means average over these.
    pub covered_count: usize,
    /// Mean milliseconds per novel view (sum of the split below).
    pub ms_per_view: f64,
    /// Mean time split.
    pub times: Times,
    /// Whether every view's time was measured here (see [`Measurement::timed`]); when not,
    /// `ms_per_view` and `times` mean nothing and the tables show no time.
    #[serde(default = "yes")]
    pub timed: bool,
}

/// A metric of a [`Measurement`], by name: what rows average and comparisons pair.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Metric {
    /// PSNR over the covered region.
    PsnrCovered,
    /// SSIM over the covered region.
    SsimCovered,
    /// LPIPS with uncovered pixels from the ground truth.
    LpipsCovered,
    /// PSNR over the whole image.
    Psnr,
    /// SSIM over the whole image.
    Ssim,
    /// LPIPS over the whole image.
    Lpips,
}

impl Metric {
    /// Every metric, covered first.
    pub const ALL: [Self; 6] = [
        Self::PsnrCovered,
        Self::SsimCovered,
        Self::LpipsCovered,
        Self::Psnr,
        Self::Ssim,
        Self::Lpips,
    ];

    /// The value of this metric in a measurement.
    pub fn of(self, m: &Measurement) -> Option<f64> {
        match self {
            Self::PsnrCovered => m.psnr_covered,
            Self::SsimCovered => m.ssim_covered,
            Self::LpipsCovered => m.lpips_covered,
            Self::Psnr => Some(m.psnr),
            Self::Ssim => Some(m.ssim),
            Self::Lpips => m.lpips,
        }
    }

    /// Whether a larger value is better (PSNR, SSIM) or worse (LPIPS).
    pub fn higher_is_better(self) -> bool {
        !matches!(self, Self::LpipsCovered | Self::Lpips)
    }

    /// Name for tables.
    pub fn label(self) -> &'static str {
        match self {
            Self::PsnrCovered => "covered PSNR",
            Self::SsimCovered => "covered SSIM",
            Self::LpipsCovered => "covered LPIPS",
            Self::Psnr => "PSNR",
            Self::Ssim => "SSIM",
            Self::Lpips => "LPIPS",
        }
    }

    fn precision(self) -> usize {
        match self {
            Self::PsnrCovered | Self::Psnr => 2,
            _ => 3,
        }
    }
}

/// A method and configuration: `(method, N, D)`.
pub type Config = (String, usize, usize);

fn key_of(m: &Measurement) -> Config {
    (m.method.clone(), m.normals, m.planes)
}

/// Indices of `(bin, kind)` groups a measurement belongs to (its own and the pooled `all`s).
fn groups_of(m: &Measurement) -> Vec<(usize, usize)> {
    let b = BINS.iter().position(|x| *x == m.bin).unwrap_or(4);
    let k = KINDS.iter().position(|x| *x == m.kind).unwrap_or(2);
    let mut out = vec![(b, k)];
    for g in [(b, 2), (4, k), (4, 2)] {
        if !out.contains(&g) {
            out.push(g);
        }
    }
    out
}

/// Aggregate measurements into rows: for every method and (N, D), every bin including `all`
/// and every kind including `all`; groups with no view are left out. Methods keep the order of
/// their first measurement. Every mean carries a bootstrap interval over the group's triplets.
pub fn aggregate(ms: &[Measurement], boot: &Bootstrap) -> Vec<Row> {
    let mut order: Vec<Config> = Vec::new();
    let mut groups: BTreeMap<(usize, usize, usize), Vec<&Measurement>> = BTreeMap::new();
    for m in ms {
        let key = key_of(m);
        let k = match order.iter().position(|o| *o == key) {
            Some(k) => k,
            None => {
                order.push(key);
                order.len() - 1
            }
        };
        for (b, kk) in groups_of(m) {
            groups.entry((k, b, kk)).or_default().push(m);
        }
    }
    groups
        .into_iter()
        .map(|((k, b, kk), v)| {
            let n = v.len() as f64;
            let mean = |f: &dyn Fn(&Measurement) -> f64| v.iter().map(|m| f(m)).sum::<f64>() / n;
            // A metric's mean and interval over the views that have it; `None` unless every
            // view has it (whole-image LPIPS, absent without weights) or at least one does
            // (covered metrics, absent where nothing is covered).
            let stat = |metric: Metric, need_all: bool| -> Option<(f64, [f64; 2])> {
                let vals: Vec<f64> = v.iter().filter_map(|m| metric.of(m)).collect();
                if vals.is_empty() || (need_all && vals.len() < v.len()) {
                    return None;
                }
                boot.mean_ci(&vals)
            };
            let full = |metric: Metric| {
                stat(metric, true).unwrap_or_else(|| {
                    let x = mean(&|m| metric.of(m).unwrap_or(f64::NAN));
                    (x, [x, x])
                })
            };
            let (psnr, psnr_ci) = full(Metric::Psnr);
            let (ssim, ssim_ci) = full(Metric::Ssim);
            let lpips = stat(Metric::Lpips, true);
            let pc = stat(Metric::PsnrCovered, false);
            let sc = stat(Metric::SsimCovered, false);
            let lc = stat(Metric::LpipsCovered, false);
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
                psnr,
                psnr_ci,
                ssim,
                ssim_ci,
                lpips: lpips.map(|x| x.0),
                lpips_ci: lpips.map(|x| x.1),
                psnr_covered: pc.map(|x| x.0),
                psnr_covered_ci: pc.map(|x| x.1),
                ssim_covered: sc.map(|x| x.0),
                ssim_covered_ci: sc.map(|x| x.1),
                lpips_covered: lc.map(|x| x.0),
                lpips_covered_ci: lc.map(|x| x.1),
                covered_fraction: mean(&|m| m.covered_fraction),
                covered_count: v.iter().filter(|m| m.psnr_covered.is_some()).count(),
                ms_per_view: times.total(),
                times,
                timed: v.iter().all(|m| m.timed),
            }
        })
        .collect()
}

/// A paired comparison of two configurations on the triplets both were scored on: the mean of
/// `a − b` for one metric in one group, with its paired bootstrap interval.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Comparison {
    /// The first configuration (`learned N=5 D=8`).
    pub a: String,
    /// The second.
    pub b: String,
    /// Rotation bin (see [`BINS`]).
    pub bin: String,
    /// Triplet kind (see [`KINDS`]).
    pub kind: String,
    /// The metric compared.
    pub metric: Metric,
    /// Triplets paired.
    pub count: usize,
    /// Mean of `a − b`.
    pub diff: f64,
    /// Its paired bootstrap interval.
    pub ci: [f64; 2],
    /// The interval contains 0: no difference can be claimed.
    pub within_noise: bool,
}

impl Comparison {
    /// `a`, `b` or `within noise`: which side the interval says is better.
    pub fn verdict(&self) -> String {
        if self.within_noise {
            "within noise".into()
        } else if (self.diff > 0.0) == self.metric.higher_is_better() {
            format!("{} better", self.a)
        } else {
            format!("{} better", self.b)
        }
    }
}

/// Paired comparisons of `a` against `b`: every metric both have, in every (bin, kind) group
/// with at least one shared triplet. Measurements pair by their `triplet`.
pub fn compare(ms: &[Measurement], a: &Config, b: &Config, boot: &Bootstrap) -> Vec<Comparison> {
    let of = |c: &Config| -> BTreeMap<usize, &Measurement> {
        ms.iter()
            .filter(|m| key_of(m) == *c)
            .map(|m| (m.triplet, m))
            .collect()
    };
    let (ma, mb) = (of(a), of(b));
    let mut out = Vec::new();
    for (bi, bin) in BINS.iter().enumerate() {
        for (ki, kind) in KINDS.iter().enumerate() {
            for metric in Metric::ALL {
                let (mut xa, mut xb) = (Vec::new(), Vec::new());
                for (t, m) in &ma {
                    let Some(n) = mb.get(t) else { continue };
                    if !groups_of(m).contains(&(bi, ki)) {
                        continue;
                    }
                    if let (Some(x), Some(y)) = (metric.of(m), metric.of(n)) {
                        xa.push(x);
                        xb.push(y);
                    }
                }
                if let Some((diff, ci)) = boot.paired(&xa, &xb) {
                    out.push(Comparison {
                        a: config_label(&a.0, a.1, a.2),
                        b: config_label(&b.0, b.1, b.2),
                        bin: (*bin).into(),
                        kind: (*kind).into(),
                        metric,
                        count: xa.len(),
                        diff,
                        ci,
                        // One pair has no spread to resample: its "interval" is a point
                        // and says nothing about noise.
                        within_noise: xa.len() < 2 || crate::stats::within_noise(ci),
                    });
                }
            }
        }
    }
    out
}

/// A row's time per view for a table cell: `–` when it was not measured here.
fn ms_cell(r: Option<&Row>) -> String {
    match r {
        Some(r) if r.timed => format!("{:.1}", r.ms_per_view),
        _ => "–".into(),
    }
}

/// `report.csv`: one line per row (intervals as `_lo`/`_hi` columns; the time columns empty
/// for renders not timed here).
pub fn csv(rows: &[Row]) -> String {
    let mut s = String::from(
        "method,normals,planes,bin,kind,count,psnr_covered,psnr_covered_lo,psnr_covered_hi,ssim_covered,ssim_covered_lo,ssim_covered_hi,lpips_covered,lpips_covered_lo,lpips_covered_hi,covered_fraction,psnr,psnr_lo,psnr_hi,ssim,ssim_lo,ssim_hi,lpips,lpips_lo,lpips_hi,ms_per_view,volume_ms,network_ms,render_ms,blend_ms\n",
    );
    let opt = |v: Option<f64>, p: usize| v.map_or(String::new(), |x| format!("{x:.p$}"));
    let ci = |c: Option<[f64; 2]>, p: usize| {
        c.map_or(",".to_string(), |c| format!("{:.p$},{:.p$}", c[0], c[1]))
    };
    for r in rows {
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{},{},{},{},{},{},{:.4},{:.4},{},{:.5},{},{},{},{}",
            r.method,
            r.normals,
            r.planes,
            r.bin,
            r.kind,
            r.count,
            opt(r.psnr_covered, 4),
            ci(r.psnr_covered_ci, 4),
            opt(r.ssim_covered, 5),
            ci(r.ssim_covered_ci, 5),
            opt(r.lpips_covered, 5),
            ci(r.lpips_covered_ci, 5),
            r.covered_fraction,
            r.psnr,
            ci(Some(r.psnr_ci), 4),
            r.ssim,
            ci(Some(r.ssim_ci), 5),
            opt(r.lpips, 5),
            ci(r.lpips_ci, 5),
            if r.timed {
                format!(
                    "{:.3},{:.3},{:.3},{:.3},{:.3}",
                    r.ms_per_view,
                    r.times.volume_ms,
                    r.times.network_ms,
                    r.times.render_ms,
                    r.times.blend_ms
                )
            } else {
                ",,,,".into()
            }
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

/// A row's value of a metric and its interval.
fn row_metric(r: &Row, m: Metric) -> Option<(f64, [f64; 2])> {
    match m {
        Metric::PsnrCovered => r.psnr_covered.zip(r.psnr_covered_ci),
        Metric::SsimCovered => r.ssim_covered.zip(r.ssim_covered_ci),
        Metric::LpipsCovered => r.lpips_covered.zip(r.lpips_covered_ci),
        Metric::Psnr => Some((r.psnr, r.psnr_ci)),
        Metric::Ssim => Some((r.ssim, r.ssim_ci)),
        Metric::Lpips => r.lpips.zip(r.lpips_ci),
    }
}

/// `29.51 [29.10, 29.92]`; a single view has no interval (`29.51 [n=1]`).
fn cell(v: Option<(f64, [f64; 2])>, prec: usize) -> String {
    v.map_or("–".into(), |(x, c)| {
        if c[0] == c[1] {
            format!("{x:.prec$} [n=1]")
        } else {
            format!("{x:.prec$} [{:.prec$}, {:.prec$}]", c[0], c[1])
        }
    })
}

/// One table: a metric per configuration × rotation bin (all kinds), with intervals.
fn metric_table(s: &mut String, rows: &[Row], metric: Metric, title: &str) {
    let cfgs = configs(rows);
    let bins_present: Vec<&str> = BINS
        .iter()
        .copied()
        .filter(|b| rows.iter().any(|r| r.bin == *b))
        .collect();
    if !rows.iter().any(|r| row_metric(r, metric).is_some()) {
        let why = if matches!(metric, Metric::Lpips | Metric::LpipsCovered) {
            "not computed (no LPIPS weights were loaded; see the note above)"
        } else {
            "not computed: no target pixel is covered"
        };
        let _ = writeln!(s, "#### {title}\n\n{why}.\n");
        return;
    }
    let _ = writeln!(s, "#### {title}\n");
    let _ = write!(s, "| method |");
    for b in &bins_present {
        let n = rows
            .iter()
            .find(|r| r.bin == *b && r.kind == "all")
            .map_or(0, |r| r.count);
        let _ = write!(s, " {} (n={n}) |", bin_label(b));
    }
    let _ = writeln!(s, " ms/view |");
    let _ = writeln!(s, "|---|{}---:|", "---:|".repeat(bins_present.len()));
    for (m, n, d) in &cfgs {
        let _ = write!(s, "| {} |", config_label(m, *n, *d));
        for b in &bins_present {
            let v = find(rows, (m, *n, *d), b, "all").and_then(|r| row_metric(r, metric));
            let _ = write!(s, " {} |", cell(v, metric.precision()));
        }
        let _ = writeln!(s, " {} |", ms_cell(find(rows, (m, *n, *d), "all", "all")));
    }
    s.push('\n');
}

/// Per method evaluated at more than one (N, D): its covered PSNR and time per view as a grid.
fn nd_sweep_tables(s: &mut String, rows: &[Row], cfgs: &[Config]) {
    let mut methods: Vec<&str> = Vec::new();
    for (m, _, _) in cfgs {
        if !methods.contains(&m.as_str()) {
            methods.push(m);
        }
    }
    for m in methods {
        let mine: Vec<&Config> = cfgs.iter().filter(|c| c.0 == m).collect();
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
            "### N × D sweep: {m} (covered PSNR dB / ms per view, all triplets)\n"
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
                        let p = r.psnr_covered.unwrap_or(f64::NAN);
                        let _ = write!(s, " {p:.2} / {} |", ms_cell(Some(r)));
                    }
                    None => s.push_str(" – |"),
                }
            }
            s.push('\n');
        }
        s.push('\n');
    }
}

/// Time per view and its parts, per configuration.
fn time_table(s: &mut String, rows: &[Row], cfgs: &[Config]) {
    let _ = writeln!(
        s,
        "### Time per novel view (ms, mean over all triplets)\n\nFrom the two decoded input images to the final image (cost volume or sweep, networks, building the MHI, render, blend), after one warm-up view; file I/O and metrics are not included.\n\n| method | cost volume | network | render | blend | total |\n|---|---:|---:|---:|---:|---:|"
    );
    for (m, n, d) in cfgs {
        if let Some(r) = find(rows, (m, *n, *d), "all", "all") {
            if !r.timed {
                let _ = writeln!(
                    s,
                    "| {} | not measured here (scored from files) | | | | |",
                    config_label(m, *n, *d)
                );
                continue;
            }
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
}

/// The tables of `report.md`: covered-region metrics first (per configuration × rotation bin,
/// with 95 % bootstrap intervals) and the covered fraction per bin, then the whole-image
/// metrics, interpolation vs extrapolation, the N × D sweep of every method run at several
/// configurations, the time split, and the paired comparisons.
pub fn markdown_tables(rows: &[Row], comparisons: &[Comparison]) -> String {
    let mut s = String::new();
    let cfgs = configs(rows);
    let _ = writeln!(
        s,
        "### Covered region\n\nScored on the target pixels that the reference view sees on the farthest plane (one geometric mask per triplet, the same for every method); each cell is the mean over triplets and its 95 % bootstrap interval. LPIPS here is computed on the whole image after the render's uncovered pixels are replaced by the ground truth's.\n"
    );
    for (metric, title) in [
        (Metric::PsnrCovered, "Covered PSNR (dB, higher is better)"),
        (Metric::SsimCovered, "Covered SSIM (higher is better)"),
        (Metric::LpipsCovered, "Covered LPIPS-alex (lower is better)"),
    ] {
        metric_table(&mut s, rows, metric, title);
    }
    let _ = writeln!(
        s,
        "Covered fraction of the target's pixels (mean over triplets), and the views with any covered pixel (the covered means average over those):\n"
    );
    let mut head = String::from("|");
    let mut sep = String::from("|");
    let mut vals = String::from("|");
    for b in BINS {
        if let Some(r) = rows.iter().find(|r| r.bin == b && r.kind == "all") {
            let _ = write!(head, " {} |", bin_label(b));
            sep.push_str("---:|");
            let _ = write!(
                vals,
                " {:.3} ({} of {} views) |",
                r.covered_fraction, r.covered_count, r.count
            );
        }
    }
    let _ = writeln!(s, "{head}\n{sep}\n{vals}\n");
    let _ = writeln!(
        s,
        "### Whole image\n\nThe papers' protocol: every pixel, including those no input view saw (rendered black by the MHI methods).\n"
    );
    for (metric, title) in [
        (Metric::Psnr, "PSNR (dB, higher is better)"),
        (Metric::Ssim, "SSIM (higher is better)"),
        (Metric::Lpips, "LPIPS-alex (lower is better)"),
    ] {
        metric_table(&mut s, rows, metric, title);
    }
    let _ = writeln!(s, "### Interpolation and extrapolation (all bins)\n");
    let _ = writeln!(
        s,
        "| method | interp. covered PSNR | extrap. covered PSNR | interp. PSNR | extrap. PSNR |\n|---|---:|---:|---:|---:|"
    );
    for (m, n, d) in &cfgs {
        let c = |kind: &str, metric: Metric| {
            cell(
                find(rows, (m, *n, *d), "all", kind).and_then(|r| row_metric(r, metric)),
                2,
            )
        };
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} |",
            config_label(m, *n, *d),
            c("interpolation", Metric::PsnrCovered),
            c("extrapolation", Metric::PsnrCovered),
            c("interpolation", Metric::Psnr),
            c("extrapolation", Metric::Psnr)
        );
    }
    s.push('\n');
    nd_sweep_tables(&mut s, rows, &cfgs);
    time_table(&mut s, rows, &cfgs);
    s.push('\n');
    s.push_str(&comparison_table(comparisons));
    s
}

/// The paired comparisons as a table: for each pair, every covered metric and the whole-image
/// PSNR over all triplets, then covered PSNR per rotation bin and per kind. A difference whose
/// interval contains 0 is reported as "within noise", never as a win.
pub fn comparison_table(comparisons: &[Comparison]) -> String {
    let mut s = String::new();
    if comparisons.is_empty() {
        return s;
    }
    let _ = writeln!(
        s,
        "### Paired comparisons\n\nMean of the per-triplet difference a − b over the triplets both were scored on, with its paired 95 % bootstrap interval (triplets resampled together). \"within noise\": the interval contains 0.\n\n| a − b | metric | bin | kind | n | mean difference [95 %] | verdict |\n|---|---|---|---|---:|---:|---|"
    );
    let mut pairs: Vec<(&str, &str)> = Vec::new();
    for c in comparisons {
        if !pairs.contains(&(c.a.as_str(), c.b.as_str())) {
            pairs.push((&c.a, &c.b));
        }
    }
    for (a, b) in pairs {
        let shown = comparisons.iter().filter(|c| {
            c.a == a
                && c.b == b
                && ((c.bin == "all"
                    && c.kind == "all"
                    && c.metric != Metric::Ssim
                    && c.metric != Metric::Lpips)
                    || (c.metric == Metric::PsnrCovered
                        && ((c.bin != "all" && c.kind == "all")
                            || (c.bin == "all" && c.kind != "all"))))
        });
        for c in shown {
            let p = c.metric.precision();
            let _ = writeln!(
                s,
                "| {a} − {b} | {} | {} | {} | {} | {:+.p$} [{:+.p$}, {:+.p$}] | {} |",
                c.metric.label(),
                c.bin,
                c.kind,
                c.count,
                c.diff,
                c.ci[0],
                c.ci[1],
                c.verdict()
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
            triplet: 0,
            psnr_covered: Some(psnr + 1.0),
            ssim_covered: Some(0.6),
            lpips_covered: Some(0.05),
            covered_fraction: 0.9,
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
            timed: true,
        }
    }

    #[test]
    fn aggregation_pools_bins_and_kinds() {
        let ms = vec![
            m("a", "0-2", "interpolation", 20.0, 1.0),
            m("a", ">8", "extrapolation", 10.0, 3.0),
            m("b", ">8", "interpolation", 30.0, 5.0),
        ];
        let rows = aggregate(&ms, &Bootstrap::default());
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
        let md = markdown_tables(&rows, &[]);
        assert!(md.find("| a N=5 D=8").unwrap() < md.find("| b N=5 D=8").unwrap());
        assert!(csv(&rows).lines().count() == rows.len() + 1);
    }

    #[test]
    fn comparisons_pair_triplets_and_refuse_to_call_noise_a_win() {
        let boot = Bootstrap::default();
        let mut ms = Vec::new();
        for t in 0..20 {
            let base = 20.0 + (t * 7 % 5) as f64;
            let mut a = m("a", "0-2", "interpolation", base + 0.5, 1.0);
            let mut b = m("b", "0-2", "interpolation", base, 1.0);
            // Covered PSNR: a and b differ by ±0.3 alternately (no real difference).
            let jitter = if t % 2 == 0 { 0.3 } else { -0.3 };
            a.psnr_covered = Some(base + jitter);
            b.psnr_covered = Some(base);
            a.triplet = t;
            b.triplet = t;
            ms.push(a);
            ms.push(b);
        }
        let ka: Config = ("a".into(), 5, 8);
        let kb: Config = ("b".into(), 5, 8);
        let c = compare(&ms, &ka, &kb, &boot);
        let get = |metric: Metric| {
            c.iter()
                .find(|x| x.metric == metric && x.bin == "all" && x.kind == "all")
                .unwrap()
                .clone()
        };
        let full = get(Metric::Psnr);
        assert_eq!(full.count, 20);
        assert!((full.diff - 0.5).abs() < 1e-9 && !full.within_noise);
        assert_eq!(full.verdict(), "a N=5 D=8 better");
        let cov = get(Metric::PsnrCovered);
        assert!(cov.within_noise, "{cov:?}");
        assert_eq!(cov.verdict(), "within noise");
        let rows = aggregate(&ms, &boot);
        let md = markdown_tables(&rows, &c);
        assert!(md.contains("within noise") && md.contains("Covered PSNR"));
        let r = rows
            .iter()
            .find(|r| r.method == "a" && r.bin == "all" && r.kind == "all")
            .unwrap();
        assert!(r.psnr_ci[0] < r.psnr && r.psnr < r.psnr_ci[1]);
        // LPIPS lower is better: a positive difference means b is better.
        let mut l = get(Metric::Psnr);
        l.metric = Metric::Lpips;
        assert_eq!(l.verdict(), "b N=5 D=8 better");
    }

    #[test]
    fn one_pair_is_never_a_win() {
        let boot = Bootstrap::default();
        let a = m("a", "0-2", "interpolation", 30.0, 1.0);
        let b = m("b", "0-2", "interpolation", 20.0, 1.0);
        let c = compare(&[a, b], &("a".into(), 5, 8), &("b".into(), 5, 8), &boot);
        assert!(!c.is_empty());
        for x in &c {
            assert_eq!(x.count, 1);
            assert!(x.within_noise, "{x:?}");
        }
    }

    #[test]
    fn renders_not_timed_here_show_no_time() {
        let boot = Bootstrap::default();
        let mut ext = m("peer", "0-2", "interpolation", 25.0, 0.0);
        ext.timed = false;
        let ms = vec![m("a", "0-2", "interpolation", 20.0, 7.0), ext];
        let rows = aggregate(&ms, &boot);
        let row = |method: &str| {
            rows.iter()
                .find(|r| r.method == method && r.bin == "all" && r.kind == "all")
                .unwrap()
        };
        assert!(row("a").timed && !row("peer").timed);
        let md = markdown_tables(&rows, &[]);
        let line = md
            .lines()
            .find(|l| l.starts_with("| peer N=5 D=8 | not measured"))
            .expect("the time table says the peer was not timed");
        assert!(!line.contains("0.0"), "{line}");
        assert!(
            md.lines()
                .any(|l| l.starts_with("| a N=5 D=8 |") && l.ends_with(" 7.0 |"))
        );
        let c = csv(&rows);
        let peer = c.lines().find(|l| l.starts_with("peer,")).unwrap();
        assert!(peer.ends_with(",,,,"), "{peer}");
        let a = c.lines().find(|l| l.starts_with("a,")).unwrap();
        assert!(a.ends_with("7.000,0.000,0.000,7.000,0.000"), "{a}");
        // A report written before the field existed reads as timed.
        let mut v = serde_json::to_value(&ms[0]).unwrap();
        v.as_object_mut().unwrap().remove("timed");
        assert!(serde_json::from_value::<Measurement>(v).unwrap().timed);
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
