//! Frames written to an MP4 come back: count, size, rate and pixels (PSNR).

use image::RgbImage;
use mhi_video::{Error, MAX_SIDE, Mp4Encoder, TITLE, decode_mp4};

/// A textured frame moving with `t`, about as hard to encode as a rendered view of a photo:
/// fine detail in brightness (sinusoids of several frequencies, a sharp-edged disc) under
/// smoothly varying colour (as in photos, whose colour is sampled coarser than their brightness
/// by the camera too).
fn frame(w: u32, h: u32, t: f32) -> RgbImage {
    RgbImage::from_fn(w, h, |x, y| {
        let (x, y) = (x as f32 + 2.0 * t, y as f32 + t);
        let s = |f: f32, p: f32| 0.5 + 0.5 * (f * x + 0.7 * f * y + p).sin();
        let disc = ((x - 60.0).powi(2) + (y - 40.0).powi(2) < 400.0) as u8 as f32;
        let luma = 0.25 * s(0.05, 0.0) + 0.2 * s(0.21, 1.0) + 0.15 * s(0.6, 2.0) + 0.3 * disc;
        let tint = [0.1 * s(0.02, 3.0), 0.05, 0.12 * s(0.015, 5.0)];
        image::Rgb(tint.map(|c| ((luma + c + 0.05).clamp(0.0, 1.0) * 255.0).round() as u8))
    })
}

fn psnr(a: &RgbImage, b: &RgbImage) -> f64 {
    let mse = a
        .as_raw()
        .iter()
        .zip(b.as_raw())
        .map(|(p, q)| (f64::from(*p) - f64::from(*q)).powi(2))
        .sum::<f64>()
        / a.as_raw().len() as f64;
    10.0 * (255.0_f64.powi(2) / mse.max(1e-12)).log10()
}

#[test]
fn frames_come_back_with_their_count_size_rate_and_pixels() {
    let (w, h, n) = (448, 256, 24);
    let input: Vec<RgbImage> = (0..n).map(|k| frame(w, h, k as f32)).collect();
    let mut enc = Mp4Encoder::new(w, h, 24.0).unwrap();
    for f in &input {
        enc.push(f).unwrap();
    }
    assert_eq!(enc.frames(), n);
    let video = enc.finish().unwrap();
    assert!((video.seconds() - 1.0).abs() < 1e-12);
    // A fast-start MP4 that says whose it is.
    assert_eq!(&video.bytes[4..8], b"ftyp");
    let moov = video.bytes.windows(4).position(|w| w == b"moov").unwrap();
    let mdat = video.bytes.windows(4).position(|w| w == b"mdat").unwrap();
    assert!(
        moov < mdat,
        "moov after mdat: a browser would wait for the whole file"
    );
    assert!(
        video
            .bytes
            .windows(TITLE.len())
            .any(|w| w == TITLE.as_bytes())
    );

    let back = decode_mp4(&video.bytes).unwrap();
    assert_eq!((back.width, back.height, back.frames.len()), (w, h, n));
    assert!((back.fps - 24.0).abs() < 0.01, "{}", back.fps);
    let worst = input
        .iter()
        .zip(&back.frames)
        .map(|(a, b)| psnr(a, b))
        .fold(f64::INFINITY, f64::min);
    eprintln!("worst {worst:.2} dB, {} bytes", video.bytes.len());
    assert!(worst >= 35.0, "worst frame {worst:.2} dB");
    // The frames are the frames given, in order, not one repeated.
    assert!(psnr(&input[0], &back.frames[n - 1]) < worst - 5.0);
}

#[test]
fn impossible_videos_are_refused() {
    for (w, h, fps) in [
        (0, 48, 10.0),
        (63, 48, 10.0),
        (64, 47, 10.0),
        (MAX_SIDE + 2, 48, 10.0),
        (64, 48, 0.0),
        (64, 48, f64::NAN),
        (64, 48, 1e9),
    ] {
        let e = Mp4Encoder::new(w, h, fps).unwrap_err();
        assert!(matches!(e, Error::Invalid(_)), "{w}x{h} at {fps}: {e}");
    }
    let mut enc = Mp4Encoder::new(64, 48, 10.0).unwrap();
    let e = enc.push(&frame(64, 50, 0.0)).unwrap_err();
    assert!(
        e.to_string()
            .contains("frame 1 is 64x50; the video is 64x48"),
        "{e}"
    );
    let e = Mp4Encoder::new(64, 48, 10.0).unwrap().finish().unwrap_err();
    assert!(e.to_string().contains("at least one frame"), "{e}");
}

#[test]
fn what_is_not_an_mp4_is_an_error_not_a_panic() {
    let mut enc = Mp4Encoder::new(64, 48, 10.0).unwrap();
    enc.push(&frame(64, 48, 0.0)).unwrap();
    let good = enc.finish().unwrap().bytes;
    let mut inputs: Vec<Vec<u8>> = vec![Vec::new(), b"not a video".to_vec(), vec![0; 4096]];
    for cut in [8, 40, good.len() / 2, good.len() - 1] {
        inputs.push(good[..cut].to_vec());
    }
    let mut flipped = good.clone();
    let mid = flipped.len() - 40;
    for b in &mut flipped[mid..] {
        *b ^= 0x5a;
    }
    inputs.push(flipped);
    for bytes in inputs {
        // Either an error or frames; never a panic.
        if let Ok(d) = decode_mp4(&bytes) {
            assert!(d.frames.len() <= 1);
        }
    }
    assert!(decode_mp4(b"").is_err());
}
