//! Golden values from scikit-image, the independent implementation.

use std::path::Path;

fn load(name: &str) -> image::Rgb32FImage {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name);
    let img = image::open(p).unwrap().to_rgb8();
    image::Rgb32FImage::from_fn(img.width(), img.height(), |x, y| {
        let q = img.get_pixel(x, y).0;
        image::Rgb([
            q[0] as f32 / 255.0,
            q[1] as f32 / 255.0,
            q[2] as f32 / 255.0,
        ])
    })
}

#[test]
fn ssim_and_psnr_match_scikit_image() {
    // Expected values computed by tests/fixtures/make_golden.py (scikit-image 0.26.0):
    //   structural_similarity(A, B, gaussian_weights=True, sigma=1.5,
    //                         use_sample_covariance=False, data_range=1, channel_axis=-1)
    //   peak_signal_noise_ratio(A, B, data_range=1)
    // with A, B the uint8 fixtures divided by 255.
    let (a, b) = (load("a.png"), load("b.png"));
    let ssim = mhi_eval::ssim(&a, &b).unwrap();
    let psnr = mhi_eval::psnr(&a, &b).unwrap();
    assert!((ssim - 0.477676967231).abs() < 1e-6, "ssim {ssim}");
    assert!((psnr - 21.544678507340).abs() < 1e-5, "psnr {psnr}");
}

#[test]
fn identical_images_and_bad_input() {
    let a = load("a.png");
    assert_eq!(mhi_eval::psnr(&a, &a).unwrap(), mhi_eval::MAX_PSNR);
    assert!((mhi_eval::ssim(&a, &a).unwrap() - 1.0).abs() < 1e-12);
    let small = image::Rgb32FImage::new(5, 5);
    assert!(mhi_eval::ssim(&small, &small).is_err());
    let other = image::Rgb32FImage::new(3, 3);
    assert!(matches!(
        mhi_eval::psnr(&a, &other),
        Err(mhi_eval::Error::SizeMismatch { .. })
    ));
}

#[test]
fn masked_psnr_counts_only_masked_pixels() {
    let (a, b) = (load("a.png"), load("b.png"));
    let n = (a.width() * a.height()) as usize;
    let all = mhi_eval::psnr_masked(&a, &b, &vec![true; n])
        .unwrap()
        .unwrap();
    assert!((all - mhi_eval::psnr(&a, &b).unwrap()).abs() < 1e-9);
    assert_eq!(
        mhi_eval::psnr_masked(&a, &b, &vec![false; n]).unwrap(),
        None
    );
    // Pixels that differ are excluded: masking to equal pixels gives the cap.
    let mask: Vec<bool> = a.pixels().zip(b.pixels()).map(|(p, q)| p == q).collect();
    if mask.iter().any(|m| *m) {
        assert_eq!(
            mhi_eval::psnr_masked(&a, &b, &mask).unwrap(),
            Some(mhi_eval::MAX_PSNR)
        );
    }
    assert!(mhi_eval::psnr_masked(&a, &b, &[true]).is_err());
}
