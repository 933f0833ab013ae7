//! The evaluation protocol must be able to fail: on synthetic scenes with exact geometry, the
//! covered-region PSNR ranks a black render and a render from the wrong pose clearly below the
//! training-free sweep, and puts the oracle (exact geometry) above a stated floor.

use image::Rgb32FImage;
use mhi_data::{Dataset, Fit, SynthConfig, TripletIndex, generate, load_frame, load_scene};
use mhi_geom::glam::DMat3;
use mhi_geom::{BlendHeuristic, Camera, NormalSet, RigidTransform, depths_linear_in_disparity};
use mhi_render::{
    Blend, LayerColor, Mhi, PixelTruth, Prune, RenderOptions, SweepConfig, oracle_alpha, render,
    sweep_mhi,
};

const FAR: f64 = 100.0;
/// The oracle's covered PSNR must stay above this on these scenes. Measured here: oracle 24.72 dB
/// mean over the 8 triplets below (N = 5, D = 32, 96 × 72), sweep 22.76, the sweep's MHI seen
/// from a pose turned by 3° 16.51, black 6.47. The oracle is not perfect on covered pixels: it
/// carries only the reference view's colour, so surfaces the reference does not see stay wrong.
/// The floor leaves room for rounding changes, not for a broken mask or renderer.
const ORACLE_FLOOR_DB: f64 = 23.5;

fn soft(mhi: &Mhi, target: &Camera) -> Rgb32FImage {
    render(
        mhi,
        target,
        &RenderOptions {
            blend: Blend::Heuristic(BlendHeuristic::Soft),
            prune: Prune::NONE,
            keep_multi_normal: false,
        },
    )
    .unwrap()
    .image
}

fn covered_psnr(img: &Rgb32FImage, truth: &Rgb32FImage, mask: &[bool]) -> f64 {
    mhi_eval::psnr_masked(img, truth, mask)
        .unwrap()
        .expect("some pixel is covered")
}

/// The target camera turned by `deg` about its own y axis: a plausible but wrong pose.
fn turned(c: &Camera, deg: f64) -> Camera {
    let r = DMat3::from_rotation_y(deg.to_radians()) * c.cam_from_world.rotation();
    let t = DMat3::from_rotation_y(deg.to_radians()) * c.cam_from_world.translation();
    Camera::new(
        c.intrinsics,
        RigidTransform::new(r, t).unwrap(),
        c.width,
        c.height,
    )
    .unwrap()
}

#[test]
fn covered_psnr_ranks_black_and_wrong_poses_below_the_sweep_and_the_oracle_above_a_floor() {
    let dir = tempfile::tempdir().unwrap();
    let config = SynthConfig {
        scenes: 4,
        frames: 8,
        width: 96,
        height: 72,
        seed: 11,
        test_fraction: 0.5,
        val_fraction: 0.0,
        ..SynthConfig::default()
    };
    generate(&config, dir.path(), &|| {}).unwrap();
    let ds = Dataset::open(dir.path(), "test", 3).unwrap();
    let index = TripletIndex::sample(&ds, 4, 3);
    assert_eq!(index.triplets.len(), 8);
    let normals = NormalSet::paper();
    let depths = depths_linear_in_disparity(1.0, FAR, 32).unwrap();
    let (mut sweep, mut black, mut wrong, mut oracle) = (0.0, 0.0, 0.0, 0.0);
    for t in &index.triplets {
        let seq = ds.sequences.iter().find(|s| s.name == t.sequence).unwrap();
        let load = |i: usize| load_frame(&seq.frames[i], None, Fit::Stretch).unwrap();
        let (rf, sf, tf) = (load(t.reference), load(t.source), load(t.target));
        let mask = mhi_eval::covered_mask(&rf.camera, &tf.camera, FAR);
        let mhi = sweep_mhi(
            &normals,
            &depths,
            &rf.camera,
            &rf.image,
            &sf.camera,
            &sf.image,
            &SweepConfig::default(),
        )
        .unwrap();
        let gt = &tf.image;
        sweep += covered_psnr(&soft(&mhi, &tf.camera), gt, &mask);
        black += covered_psnr(&Rgb32FImage::new(gt.width(), gt.height()), gt, &mask);
        wrong += covered_psnr(&soft(&mhi, &turned(&tf.camera, 3.0)), gt, &mask);
        let scene = load_scene(&seq.dir().join("scene.json")).unwrap();
        let truth: Vec<Option<PixelTruth>> = scene
            .ground_truth(&rf.camera)
            .into_iter()
            .map(|t| t.map(|(normal, depth)| PixelTruth { normal, depth }))
            .collect();
        let exact = Mhi::new(
            normals.clone(),
            depths.clone(),
            rf.camera,
            LayerColor::Shared(rf.image.clone()),
            oracle_alpha(&normals, &depths, &rf.camera, &truth),
        )
        .unwrap();
        oracle += covered_psnr(&soft(&exact, &tf.camera), gt, &mask);
    }
    let n = index.triplets.len() as f64;
    let (sweep, black, wrong, oracle) = (sweep / n, black / n, wrong / n, oracle / n);
    eprintln!(
        "covered PSNR: sweep {sweep:.2}, black {black:.2}, 3° wrong pose {wrong:.2}, oracle {oracle:.2}"
    );
    assert!(black < sweep - 8.0, "black {black} vs sweep {sweep}");
    assert!(wrong < sweep - 2.0, "wrong pose {wrong} vs sweep {sweep}");
    assert!(oracle > ORACLE_FLOOR_DB, "oracle {oracle}");
    assert!(oracle > sweep, "oracle {oracle} vs sweep {sweep}");
}
