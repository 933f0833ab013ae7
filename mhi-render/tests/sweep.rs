//! The plane-sweep volume agrees with exact geometry: on a synthetic scene, the source image seen
//! on the plane nearest each reference pixel's true surface reproduces the reference pixel.

use mhi_data::{SynthConfig, make_scene};
use mhi_geom::{NormalSet, depths_linear_in_disparity};
use mhi_render::{PixelTruth, oracle_alpha, plane_sweep_volume};

#[test]
fn sweep_volume_matches_the_reference_on_the_true_planes() {
    // Three scenes of at least four frames (the default has ten), rendered 3x supersampled.
    let config = SynthConfig {
        width: 96,
        height: 72,
        seed: 21,
        ..SynthConfig::default()
    };
    for s in 0..3 {
        let scene = make_scene(&config, s).unwrap();
        let (reference, source) = (scene.cameras[0], scene.cameras[3]);
        let (ref_img, src_img) = (scene.render(0, 3), scene.render(3, 3));
        let normals = NormalSet::paper_subset(1).unwrap();
        let depths = depths_linear_in_disparity(1.0, 100.0, 96).unwrap();
        let truth: Vec<Option<PixelTruth>> = scene
            .ground_truth(&reference)
            .into_iter()
            .map(|t| t.map(|(normal, depth)| PixelTruth { normal, depth }))
            .collect();
        let best = oracle_alpha(&normals, &depths, &reference, &truth);
        let psv = plane_sweep_volume(&normals, &depths, &reference, &src_img, &source).unwrap();
        let px = 96 * 72;
        let (mut on_truth, mut n_truth, mut off_truth, mut n_off) = (0.0, 0, 0.0, 0);
        for p in 0..px {
            let Some(j) = (0..depths.len()).find(|j| best[j * px + p] > 0.5) else {
                continue;
            };
            let r = ref_img.as_raw();
            let err = |jj: usize| -> Option<f32> {
                (psv.plane_valid(0, jj)[p] > 0.0).then(|| {
                    (0..3)
                        .map(|k| (psv.plane_rgb(0, jj)[3 * p + k] - r[3 * p + k]).abs())
                        .sum::<f32>()
                        / 3.0
                })
            };
            if let Some(e) = err(j) {
                on_truth += e;
                n_truth += 1;
            }
            let far_off = (j + depths.len() / 2) % depths.len();
            if let Some(e) = err(far_off) {
                off_truth += e;
                n_off += 1;
            }
        }
        let (on, off) = (on_truth / n_truth as f32, off_truth / n_off as f32);
        eprintln!(
            "scene {s}: mean |psv − ref| on the true plane {on:.4} ({n_truth} px), on a wrong plane {off:.4}"
        );
        assert!(n_truth > px / 3);
        assert!(on < 0.06, "scene {s}: {on}");
        assert!(off > 2.0 * on, "scene {s}: {off} vs {on}");
    }
}
