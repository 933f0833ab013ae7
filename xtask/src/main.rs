//! `cargo xtask`: the project's command line. Each task lives in its own module.

mod data;
mod progress;

use clap::Parser;

/// Multiple Homography Image view synthesis: the project's tasks.
///
/// Run `cargo xtask <TASK> --help` for the options of a task.
#[derive(Parser, Debug)]
#[command(name = "cargo xtask", version, about, long_about = None)]
enum Task {
    /// Generate synthetic posed scenes (rooms and courtyards of textured planes) in
    /// RealEstate10K layout, with exact ground-truth planes in each scene's scene.json.
    Synth(data::SynthArgs),
    /// Open a dataset in RealEstate10K layout, report its sequences and sample evaluation
    /// triplets binned by rotation (optionally saving them as a JSON index).
    Triplets(data::TripletsArgs),
}

fn main() {
    let result = match Task::parse() {
        Task::Synth(a) => data::synth(&a),
        Task::Triplets(a) => data::triplets(&a),
    };
    if let Err(e) = result {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}
