//! `cargo xtask bench --ops`: every kind of op of the default model's training step timed alone
//! on its real shapes (stage 1's 3D U-Net at 64 × 64 with N = 5, D = 8; the VGG16 taps of the
//! perceptual loss; the warp; the layer norm over channels), forward and forward +
//! backward, beside the same ops in PyTorch (`xtask/scripts/ops_torch.py`) in the same run.

use std::path::Path;

use burn::tensor::ops::{ConvOptions, ConvTransposeOptions};
use burn::tensor::{Device, Distribution, Tensor};

use super::median_ms;

/// One op at one shape: what it is and its parameters, shared with the PyTorch twin.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct OpSpec {
    /// Key shared with the PyTorch script.
    pub name: String,
    /// `conv3d`, `conv3d_as_2d` (the same sums through a 2D kernel; PyTorch runs conv3d),
    /// `convT3d`, `layernorm5`, `conv2d`, `grid_sample`.
    pub kind: String,
    /// Input shape.
    pub input: Vec<usize>,
    /// Output channels (convolutions).
    pub cout: usize,
    /// Stride in the image axes.
    pub stride: usize,
    /// Dilation in the image axes.
    pub dilation: usize,
}

/// The ops of one phase-1 step of the default model (N = 5, D = 8, 64 × 64, widths 8/16/32),
/// from `xtask/scripts/ops.json` (the table the PyTorch twin is handed too).
pub fn default_ops() -> Vec<OpSpec> {
    serde_json::from_str(include_str!("../../../xtask/scripts/ops.json"))
        .expect("xtask/scripts/ops.json is a list of op specs (checked by a test)")
}

fn rand<const D: usize>(shape: [usize; D], device: &Device) -> Tensor<D> {
    Tensor::random(shape, Distribution::Uniform(-1.0, 1.0), device)
}

fn dims5(v: &[usize]) -> [usize; 5] {
    [v[0], v[1], v[2], v[3], v[4]]
}

fn dims4(v: &[usize]) -> [usize; 4] {
    [v[0], v[1], v[2], v[3]]
}

/// The op as a closure returning a scalar, its inputs on `device` (tracked when `grad`).
fn op_fn(op: &OpSpec, device: &Device, grad: bool) -> Box<dyn Fn() -> Tensor<1>> {
    let (s, dl) = (op.stride, op.dilation);
    let g = |t: Tensor<5>| if grad { t.require_grad() } else { t };
    let g4 = |t: Tensor<4>| if grad { t.require_grad() } else { t };
    match op.kind.as_str() {
        "conv3d" => {
            let x = g(rand(dims5(&op.input), device));
            let w = g(rand([op.cout, op.input[1], 3, 3, 3], device));
            let o = ConvOptions::new([1, s, s], [1, dl, dl], [1, dl, dl], 1);
            Box::new(move || {
                mhi_net::fastconv::conv3d(x.clone(), w.clone(), None, o.clone()).mean()
            })
        }
        "conv3d_as_2d" => {
            let x = g(rand(dims5(&op.input), device));
            let w = g(rand([op.cout, op.input[1], 3, 3, 3], device));
            Box::new(move || {
                mhi_net::conv3d_planes_as_2d(x.clone(), w.clone(), None, s, dl, dl).mean()
            })
        }
        "convT3d" => {
            let x = g(rand(dims5(&op.input), device));
            let w = g(rand([op.input[1], op.cout, 1, 2, 2], device));
            let o = ConvTransposeOptions::new([1, s, s], [0, 0, 0], [0, 0, 0], [1, 1, 1], 1);
            Box::new(move || {
                mhi_net::fastconv::conv_transpose3d(x.clone(), w.clone(), None, o.clone()).mean()
            })
        }
        "layernorm5" => {
            // The model's layer norm over channels (no permutes on the CPU backend; PyTorch's
            // twin permutes the channels last and back).
            let norm = burn::nn::LayerNormConfig::new(op.input[1]).init(device);
            let x = g(rand(dims5(&op.input), device));
            Box::new(move || mhi_net::fastconv::channel_norm(&norm, 1e-5, x.clone()).mean())
        }
        "conv2d" => {
            let x = g4(rand(dims4(&op.input), device));
            let w = g4(rand([op.cout, op.input[1], 3, 3], device));
            let o = ConvOptions::new([1, 1], [1, 1], [1, 1], 1);
            Box::new(move || {
                mhi_net::fastconv::conv2d(x.clone(), w.clone(), None, o.clone()).mean()
            })
        }
        _ => {
            // The warp: bilinear, zero padding, the warp's layout. On the CPU backend the model
            // gathers through taps built once per sample from its grid (`mhi_render::diff::Taps`,
            // outside the timing, as in training); elsewhere it is `grid_sample`.
            let [b, c, h, w] = dims4(&op.input);
            let x = g4(rand([b, c, h, w], device));
            let grid: Tensor<4> = rand([b, h, w, 2], device);
            let values = grid
                .to_data()
                .convert::<f32>()
                .try_to_vec::<f32>()
                .unwrap_or_default();
            let valid = vec![1.0f32; b * h * w];
            let taps = std::sync::Arc::new(mhi_render::diff::Taps::new(
                &values,
                &valid,
                b,
                (w, h),
                (w, h),
            ));
            Box::new(move || mhi_render::diff::gather::warp(x.clone(), &taps).mean())
        }
    }
}

/// Forward (plain device, no graph) and forward + backward (autodiff device) median
/// milliseconds of one op in burn.
fn time_burn(op: &OpSpec, runs: usize) -> (f64, f64) {
    let plain = Device::flex();
    let fwd = op_fn(op, &plain, false);
    let f = median_ms(runs, || {
        let _ = fwd().into_data();
    });
    let both = op_fn(op, &plain.autodiff(), true);
    let b = median_ms(runs, || {
        let _ = both().backward();
    });
    (f, b)
}

/// Time every op in burn and, with `peer`, in PyTorch; print the table and return it as JSON.
pub fn ops(
    python: &str,
    peer: Option<&Path>,
    threads: usize,
    runs: usize,
) -> anyhow::Result<serde_json::Value> {
    let specs = default_ops();
    let torch: Option<serde_json::Value> = match peer {
        Some(script) => {
            let tmp = tempfile::tempdir()?;
            let spec_path = tmp.path().join("ops.json");
            std::fs::write(&spec_path, serde_json::to_vec(&specs)?)?;
            println!("running the PyTorch twin {} ...", script.display());
            let mut cmd = std::process::Command::new(python);
            cmd.arg(script).arg(&spec_path).args([
                "--threads",
                &threads.to_string(),
                "--runs",
                &runs.to_string(),
            ]);
            Some(super::run_peer_json(&mut cmd, script)?)
        }
        None => None,
    };
    println!(
        "\n{:<30} {:>9} {:>9} {:>9} {:>9} {:>7} {:>7}",
        "op (forward; fwd+bwd)", "burn fwd", "torch", "burn f+b", "torch", "fwd ×", "f+b ×"
    );
    let mut rows = Vec::new();
    let (mut sum_b, mut sum_t) = (0.0, 0.0);
    for op in &specs {
        let (bf, bb) = time_burn(op, runs);
        let t = torch.as_ref().and_then(|t| t["ops"].get(&op.name));
        let tf = t.and_then(|t| t["forward_ms"].as_f64());
        let tb = t.and_then(|t| t["forward_backward_ms"].as_f64());
        sum_b += bb;
        sum_t += tb.unwrap_or(f64::NAN);
        let f = |v: Option<f64>| v.map_or("-".to_string(), |x| format!("{x:.1}"));
        let r = |a: f64, b: Option<f64>| b.map_or("-".to_string(), |b| format!("{:.1}", a / b));
        println!(
            "{:<30} {bf:>9.1} {:>9} {bb:>9.1} {:>9} {:>7} {:>7}",
            op.name,
            f(tf),
            f(tb),
            r(bf, tf),
            r(bb, tb)
        );
        rows.push(serde_json::json!({
            "op": op.name, "burn_forward_ms": bf, "burn_forward_backward_ms": bb,
            "torch_forward_ms": tf, "torch_forward_backward_ms": tb,
        }));
    }
    println!(
        "{:<30} {:>9} {:>9} {sum_b:>9.1} {:>9.1} {:>7} {:>7.1}",
        "sum (fwd+bwd)",
        "",
        "",
        sum_t,
        "",
        sum_b / sum_t
    );
    Ok(serde_json::json!({ "threads": threads, "runs": runs, "ops": rows, "torch": torch }))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The op table parses, holds every kind the timer knows and nothing else (an unknown kind
    /// would be timed as a grid sample).
    #[test]
    fn the_op_table_parses_with_known_kinds() {
        let ops = default_ops();
        assert_eq!(ops.len(), 31);
        let known = [
            "conv3d",
            "conv3d_as_2d",
            "convT3d",
            "layernorm5",
            "conv2d",
            "grid_sample",
        ];
        for o in &ops {
            assert!(known.contains(&o.kind.as_str()), "{o:?}");
            let rank = if o.kind == "conv2d" || o.kind == "grid_sample" {
                4
            } else {
                5
            };
            assert_eq!(o.input.len(), rank, "{o:?}");
        }
    }
}
