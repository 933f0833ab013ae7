//! The pretrained model shipped in `models/` loads, is the model its MODEL.md describes (the
//! sweep prior, N = 5, D = 16, a colour head, a stage 1 of width 16), and a copy whose
//! config.json no longer matches its weights is refused with a message that says so; the MPI
//! baseline beside it shares its recipe; the previous pretrained models (width 8, with and
//! without a colour head) and their MPIs still load.

use std::path::{Path, PathBuf};

use burn::tensor::Device;
use mhi_net::{Model, Prior};

/// Rounds of blending steps in the shipped MHI's training (one: 8,400 stage-1 steps, then 400
/// blending steps).
const BLEND_ROUNDS: usize = 1;

fn model(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../models")
        .join(name)
}

/// The model `render` and `eval` use by default (`mhi_net::pretrained`).
fn shipped() -> PathBuf {
    model("mhi-n5d16-colour-w16")
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap().flatten() {
        let p = e.path();
        if p.is_dir() {
            copy_dir(&p, &to.join(e.file_name()));
        } else {
            std::fs::copy(&p, to.join(e.file_name())).unwrap();
        }
    }
}

#[test]
fn the_shipped_model_loads_and_a_mismatched_config_is_refused() {
    let dir = shipped();
    assert!(
        dir.join("MODEL.md").is_file(),
        "{} has no MODEL.md",
        dir.display()
    );
    let m = Model::load(&dir, Device::flex()).unwrap();
    assert_eq!(m.config().prior, Prior::Sweep);
    assert!(
        m.config().stage1.unet.colour_head,
        "the shipped model has a colour head"
    );
    assert_eq!(m.config().stage1.unet.width, 16);
    assert_eq!((m.normals().len(), m.depths().len()), (5, 16));
    assert!(
        m.blend_trained(),
        "the shipped model's blending network was trained"
    );

    let d = tempfile::tempdir().unwrap();
    copy_dir(&dir, d.path());
    let cfg = d.path().join("config.json");
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&cfg).unwrap()).unwrap();
    v["stage1"]["unet"]["width"] = serde_json::json!(8);
    std::fs::write(&cfg, serde_json::to_string(&v).unwrap()).unwrap();
    let err = Model::load(d.path(), Device::flex())
        .err()
        .expect("refused")
        .to_string();
    assert!(
        err.contains("does not match this run's config.json"),
        "{err}"
    );
}

/// The learned MPI baseline shipped beside it has the same recipe with one normal.
#[test]
fn the_mpi_baseline_loads_with_the_same_recipe() {
    let mpi = Model::load(&model("mpi-n1d16-colour-w16"), Device::flex()).unwrap();
    let mhi = Model::load(&shipped(), Device::flex()).unwrap();
    assert_eq!((mpi.normals().len(), mpi.depths().len()), (1, 16));
    let (a, b) = (mpi.config(), mhi.config());
    assert_eq!(a.prior, b.prior);
    assert_eq!((a.width, a.height, a.lr), (b.width, b.height, b.lr));
    assert_eq!(a.stage1.scale, b.stage1.scale);
    assert_eq!(a.stage1.unet.width, b.stage1.unet.width);
    assert_eq!(
        (a.lr_drop_at, a.lr_drop_factor),
        (b.lr_drop_at, b.lr_drop_factor)
    );
    assert!(a.stage1.unet.colour_head && b.stage1.unet.colour_head);
    assert_eq!(a.data, b.data);
    // The same stage-1 steps: the MHI's config counts its blending steps into phase 1's end
    // (BLEND_ROUNDS rounds of 400 between its stage-1 parts); the MPI has no blending phase.
    assert_eq!(mpi.step(), a.phase1_steps);
    assert_eq!(a.phase1_steps, b.phase1_steps - (BLEND_ROUNDS - 1) * 400);
    assert_eq!(mhi.step(), b.phase1_steps + b.phase2_steps);
}

/// The previous pretrained model (no colour head, 8,200 steps) and its MPI still load, with the
/// recipe their MODEL.md gives.
#[test]
fn the_previous_model_and_its_mpi_still_load() {
    let mhi = Model::load(&model("mhi-n5d16"), Device::flex()).unwrap();
    let mpi = Model::load(&model("mpi-n1d16"), Device::flex()).unwrap();
    assert!(!mhi.config().stage1.unet.colour_head);
    assert_eq!((mpi.normals().len(), mpi.depths().len()), (1, 16));
    let (a, b) = (mpi.config(), mhi.config());
    // Both trained their stage 1 for 6,600 steps. The MHI's were interleaved with three rounds
    // of 400 blending steps (1,800, 400 blending, then after each of three resumes 1,600, 2,400
    // and 800 more and 400 blending), so its config counts phase 1 to step 7,800; the MPI has
    // no blending phase and ends at its phase 1.
    assert_eq!(mpi.step(), a.phase1_steps);
    assert_eq!(a.phase1_steps, b.phase1_steps - 3 * 400);
    assert_eq!(mhi.step(), b.phase1_steps + b.phase2_steps);
}

/// The pretrained model before the current one (width 8, 3,900 stage-1 steps and 400 blending
/// steps) and its MPI still load, with the same recipe.
#[test]
fn the_width_8_model_and_its_mpi_still_load() {
    let mhi = Model::load(&model("mhi-n5d16-colour"), Device::flex()).unwrap();
    let mpi = Model::load(&model("mpi-n1d16-colour"), Device::flex()).unwrap();
    let (a, b) = (mpi.config(), mhi.config());
    assert_eq!((a.stage1.unet.width, b.stage1.unet.width), (8, 8));
    assert!(a.stage1.unet.colour_head && b.stage1.unet.colour_head);
    assert_eq!((mpi.normals().len(), mhi.normals().len()), (1, 5));
    assert_eq!(mpi.step(), a.phase1_steps);
    assert_eq!((a.phase1_steps, mhi.step()), (3_900, 4_300));
}
