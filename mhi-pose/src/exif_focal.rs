//! A photo's focal length from its EXIF (kamadak-exif): the 35 mm-equivalent focal length, or
//! the focal length with the focal plane's resolution.

use std::path::Path;

use serde::{Deserialize, Serialize};

/// What a photo's EXIF says about its focal length.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum ExifFocal {
    /// `FocalLengthIn35mmFilm`, in millimetres: the focal length a 36 × 24 mm frame with the
    /// same diagonal field of view would have.
    Equivalent35mm(f64),
    /// `FocalLength` in millimetres with `FocalPlaneXResolution` in pixels per millimetre.
    FocalPlane {
        /// The focal length, mm.
        focal_mm: f64,
        /// Sensor pixels per millimetre.
        pixels_per_mm: f64,
    },
}

/// The diagonal of a 36 × 24 mm frame, in millimetres.
const FULL_FRAME_DIAGONAL_MM: f64 = 43.266_615_305_567_87;

impl ExifFocal {
    /// The focal length in pixels of a `width × height` image (upright or not: the diagonal
    /// does not turn).
    pub fn focal_px(&self, width: u32, height: u32) -> f64 {
        match *self {
            Self::Equivalent35mm(mm) => {
                let diagonal = f64::from(width).hypot(f64::from(height));
                mm / FULL_FRAME_DIAGONAL_MM * diagonal
            }
            Self::FocalPlane {
                focal_mm,
                pixels_per_mm,
            } => focal_mm * pixels_per_mm,
        }
    }

    /// For a person.
    pub fn describe(&self) -> String {
        match *self {
            Self::Equivalent35mm(mm) => format!("35 mm-equivalent focal length {mm:.0} mm"),
            Self::FocalPlane {
                focal_mm,
                pixels_per_mm,
            } => format!(
                "focal length {focal_mm:.2} mm at {pixels_per_mm:.1} pixels per mm of the focal plane"
            ),
        }
    }
}

/// The EXIF focal length of the photo at `path`, if it records a usable one.
pub fn exif_focal(path: &Path) -> Option<ExifFocal> {
    let file = std::fs::File::open(path).ok()?;
    let exif = exif::Reader::new()
        .read_from_container(&mut std::io::BufReader::new(file))
        .ok()?;
    let num = |tag: exif::Tag| -> Option<f64> {
        let f = exif.get_field(tag, exif::In::PRIMARY)?;
        match &f.value {
            exif::Value::Rational(v) => v.first().map(|r| r.to_f64()),
            exif::Value::SRational(v) => v.first().map(|r| r.to_f64()),
            v => v.get_uint(0).map(f64::from),
        }
        .filter(|x| x.is_finite() && *x > 0.0)
    };
    if let Some(mm) = num(exif::Tag::FocalLengthIn35mmFilm) {
        return Some(ExifFocal::Equivalent35mm(mm));
    }
    let focal_mm = num(exif::Tag::FocalLength)?;
    let resolution = num(exif::Tag::FocalPlaneXResolution)?;
    // FocalPlaneResolutionUnit: 2 = inch (the default), 3 = centimetre, 4 = millimetre.
    let unit_mm = match exif
        .get_field(exif::Tag::FocalPlaneResolutionUnit, exif::In::PRIMARY)
        .and_then(|f| f.value.get_uint(0))
    {
        Some(3) => 10.0,
        Some(4) => 1.0,
        _ => 25.4,
    };
    Some(ExifFocal::FocalPlane {
        focal_mm,
        pixels_per_mm: resolution / unit_mm,
    })
}
