//! Time `mhi_pose::estimate` on two photos: `cargo run --release -p mhi-pose --example time_pose
//! -- A.jpg B.jpg [RUNS]`. Prints each run's seconds and the median, then the pose's summary
//! and its rotation and translation to the last bit (to compare two builds).

use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (Some(a), Some(b)) = (args.first(), args.get(1)) else {
        return Err("usage: time_pose A.jpg B.jpg [RUNS]".into());
    };
    let runs: usize = args.get(2).map_or(Ok(5), |r| r.parse())?;
    let reference = mhi_pose::Photo::open(a.as_ref())?;
    let source = mhi_pose::Photo::open(b.as_ref())?;
    let options = mhi_pose::Options::default();
    let mut seconds = Vec::with_capacity(runs);
    let mut last = None;
    for _ in 0..runs.max(1) {
        let t = Instant::now();
        last = Some(mhi_pose::estimate(&reference, &source, &options)?);
        seconds.push(t.elapsed().as_secs_f64());
    }
    let shown: Vec<String> = seconds.iter().map(|s| format!("{s:.3}")).collect();
    println!("runs (s): {}", shown.join(" "));
    println!("median: {:.3} s", mhi_pose::accuracy::median(&seconds));
    if let Some(pair) = last {
        println!("{}", pair.summary());
        // Every bit, so that two builds can be compared.
        println!("rotation {:?}", pair.rotation().to_cols_array());
        println!("translation {:?}", pair.translation().to_array());
    }
    Ok(())
}
