//! The pictures of a report: sample sheets, the MHI layers of one scene and the orbit GIF.

use super::*;

pub(super) fn file_label(o: &Output) -> String {
    if o.normals == 0 {
        o.method.clone()
    } else {
        format!("{}_n{}_d{}", o.method, o.normals, o.planes)
    }
}

/// One sample: images and error maps in `samples/NNN/`, and the markdown table showing them.
pub(super) fn write_samples(
    out: &Path,
    k: usize,
    t: &mhi_data::Triplet,
    (rf, sf): (&LoadedFrame, &LoadedFrame),
    gt: &Rgb32FImage,
    covered: &[bool],
    outputs: &[Output],
) -> anyhow::Result<String> {
    let dir = out.join("samples").join(format!("{k:03}"));
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let f = factor_for(gt.width(), 192);
    let save = |name: &str, img: &Rgb32FImage| -> anyhow::Result<String> {
        let file = format!("{name}.png");
        mhi_data::write_png(
            &dir.join(&file),
            &enlarge(&mhi_data::to_u8(&clipped(img)), f),
        )?;
        Ok(format!("samples/{k:03}/{file}"))
    };
    let mut md = format!(
        "#### Sample {k}: {} frames {} + {} → {} ({}, {:.1}° max rotation)\n\n",
        mhi_data::sanitize::for_markdown(&t.sequence),
        t.reference,
        t.source,
        t.target,
        match t.kind {
            TripletKind::Interpolation => "interpolation",
            TripletKind::Extrapolation => "extrapolation",
        },
        t.max_rotation_deg
    );
    let mut head = String::from("| reference | source | ground truth |");
    let mut row = format!(
        "| <img src=\"{}\" width=\"160\"> | <img src=\"{}\" width=\"160\"> | <img src=\"{}\" width=\"160\"> |",
        save("reference", &rf.image)?,
        save("source", &sf.image)?,
        save("ground_truth", gt)?
    );
    let mut dimmed = gt.clone();
    for (p, &c) in dimmed.pixels_mut().zip(covered) {
        if !c {
            for v in &mut p.0 {
                *v *= 0.25;
            }
        }
    }
    let mut err_row = format!(
        "| | | <img src=\"{}\" width=\"160\"><br>*covered region (uncovered dimmed); below: error ×4* |",
        save("covered", &dimmed)?
    );
    for o in outputs {
        let name = file_label(o);
        let img = clipped(&o.image);
        let p = crate::psnr_masked(&img, gt, covered)?
            .map_or("no covered pixel".to_string(), |p| {
                format!("{p:.1} dB covered")
            });
        let _ = write!(
            head,
            " {} ({p}) |",
            config_label(&o.method, o.normals, o.planes)
        );
        let _ = write!(row, " <img src=\"{}\" width=\"160\"> |", save(&name, &img)?);
        let errp = save(
            &format!("{name}_error"),
            &crate::images::error_map(&img, gt),
        )?;
        let _ = write!(err_row, " <img src=\"{errp}\" width=\"160\"> |");
    }
    let sep = format!("|{}", "---|".repeat(3 + outputs.len()));
    let _ = writeln!(md, "{head}\n{sep}\n{row}\n{err_row}\n");
    Ok(md)
}

/// The MHI layers of the first triplet's scene (first run with N > 1, else the sweep), the
/// multi-normal images and blend weights in the target, and an orbit GIF.
pub(super) fn write_layers_and_orbit(
    a: &EvalArgs,
    models: &[Loaded],
    rf: &LoadedFrame,
    sf: &LoadedFrame,
    tf: &LoadedFrame,
) -> anyhow::Result<Option<f64>> {
    let dir = a.out.join("layers");
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let model = models
        .iter()
        .find(|m| m.model.normals().len() > 1)
        .or(models.first());
    let source = match model {
        Some(m) => MhiSource::Learned(&m.model),
        None => MhiSource::Sweep {
            normals: NormalSet::paper(),
            depths: a.range.depths(8)?,
            config: SweepConfig::for_short_side(rf.image.width().min(rf.image.height())),
        },
    };
    let synth = ViewSynthesis::new(source);
    let (mhi, _) = synth.mhi(rf, sf)?;
    let (w, h) = (rf.image.width(), rf.image.height());
    let px = (w * h) as usize;
    let f = factor_for(w, 96);
    for i in 0..mhi.n() {
        let tiles: Vec<_> = (0..mhi.d())
            .map(|j| {
                let k = i * mhi.d() + j;
                enlarge(
                    &layer_picture(&rf.image, &mhi.alpha()[k * px..(k + 1) * px]),
                    f,
                )
            })
            .collect();
        mhi_data::write_png(&dir.join(format!("normal_{i}.png")), &strip(&tiles))?;
    }
    let r = multi_normal(&mhi, &tf.camera, Prune::NONE)?;
    // A blending network that reads each normal's photo-inconsistency is given it.
    let reads_inc = synth
        .model()
        .and_then(|m| m.blend_consistency().map(|beta| (m, beta)))
        .filter(|_| mhi.n() > 1);
    let weights = match reads_inc {
        Some((m, _)) => {
            let inc = mhi_net::inconsistency(&mhi, rf, sf, &tf.camera)?;
            r.blend_learned_with(&mhi, m, &tf.camera, &inc)?.weights
        }
        None => {
            r.blend(&mhi, synth.model(), &tf.camera, BlendChoice::Learned)?
                .weights
        }
    };
    let (tw, th) = (tf.image.width(), tf.image.height());
    let tpx = (tw * th) as usize;
    let mni: Vec<_> = r
        .images
        .iter()
        .map(|m| enlarge(&mhi_data::to_u8(&clipped(m)), f))
        .collect();
    let wts: Vec<_> = (0..mhi.n())
        .map(|i| {
            enlarge(
                &crate::images::grey(&weights[i * tpx..(i + 1) * tpx], tw, th),
                f,
            )
        })
        .collect();
    mhi_data::write_png(&dir.join("multi_normal.png"), &strip(&mni))?;
    mhi_data::write_png(&dir.join("weights.png"), &strip(&wts))?;

    if let Some(dir) = &a.export {
        let soft =
            heuristic_weights_for(mhi.normals(), &rf.camera, &tf.camera, BlendHeuristic::Soft);
        let plan = mhi_render::plan::analyse(&mhi, &[(&tf.camera, &soft[..])], a.prune())?;
        mhi_viewer::write_viewer(
            dir,
            &mhi,
            &plan,
            if synth.model().is_some() {
                "trained stage 1 of the first triplet (the viewer blends with Soft)"
            } else {
                "training-free plane sweep of the first triplet"
            },
            &[
                ("reference photo", &rf.camera),
                ("source photo", &sf.camera),
            ],
            &[("target photo".to_string(), &tf.camera)],
            None,
        )?;
    }
    let mut rotation = None;
    if a.orbit_frames > 0 {
        let baseline = (rf.camera.center_in_world() - sf.camera.center_in_world()).length();
        let cams = mhi_geom::path::orbit(
            &rf.camera,
            0.5 * baseline,
            a.orbit_frames,
            crate::images::median_depth(&mhi),
        )?;
        rotation = Some(mhi_geom::path::PathRange::of(&rf.camera, &cams).max_rotation_deg);
        let consistency = reads_inc
            .map(|(_, beta)| mhi_net::Consistency::new(&mhi, rf, sf, beta))
            .transpose()?;
        let mut frames = Vec::new();
        for c in &cams {
            let img = match &consistency {
                Some(k) => k.render_with(&mhi, synth.model(), c, a.prune())?.image,
                None => crate::images::view(&mhi, synth.model(), c, a.prune())?.0,
            };
            frames.push(enlarge(
                &mhi_data::to_u8(&clipped(&img)),
                factor_for(img.width(), 256),
            ));
        }
        crate::images::write_gif(&a.out.join("orbit.gif"), &frames, 80)?;
    }
    Ok(rotation)
}
