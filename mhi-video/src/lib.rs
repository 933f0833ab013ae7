//! Frames to an H.264 MP4 that browsers play, and back.
//!
//! [`Mp4Encoder`] takes 8-bit RGB frames of one size, converts them to YUV 4:2:0 (BT.601,
//! limited range, as the stream's VUI says), encodes them with OpenH264 (built from the source
//! its crate bundles) and muxes them into a fast-start MP4 (`moov` before `mdat`) with muxide.
//! [`decode_mp4`] reads such a file back with a second implementation of the container (the
//! `mp4` crate) and OpenH264's decoder, so a test or a user can check what was written.
//! No system binary is needed at run time.
//!
//! ```
//! use image::RgbImage;
//! use mhi_video::{Mp4Encoder, decode_mp4};
//!
//! let mut enc = Mp4Encoder::new(64, 48, 10.0).unwrap();
//! for k in 0..5u8 {
//!     enc.push(&RgbImage::from_fn(64, 48, |x, y| image::Rgb([x as u8 * 4, y as u8 * 5, k * 40]))).unwrap();
//! }
//! let video = enc.finish().unwrap();
//! let back = decode_mp4(&video.bytes).unwrap();
//! assert_eq!((back.frames.len(), back.width, back.height), (5, 64, 48));
//! ```

use std::io::Cursor;

use image::RgbImage;
use muxide::api::{Metadata, Muxer, MuxerBuilder, VideoCodec};
use openh264::OpenH264API;
use openh264::decoder::{DecodedYUV, Decoder, DecoderConfig};
use openh264::encoder::{
    BitRate, Complexity, Encoder, EncoderConfig, FrameRate, FrameType, IntraFramePeriod, QpRange,
    RateControlMode, VuiConfig,
};
use openh264::formats::{YUVBuffer, YUVSource};

/// The title every video this crate writes carries in its metadata (`udta`), so that a tool can
/// tell its own videos from a user's.
pub const TITLE: &str = "MHI view synthesis";

/// The largest side a video may have: far beyond a render's, and within what browsers decode.
pub const MAX_SIDE: u32 = 4096;

/// Why a video could not be written or read.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// Parameters that describe no playable video.
    #[error("{0}")]
    Invalid(String),
    /// The encoder or decoder failed.
    #[error("H.264 {what}: {message}")]
    Codec {
        /// Encoding or decoding.
        what: &'static str,
        /// OpenH264's message.
        message: String,
    },
    /// The container could not be written or read.
    #[error("MP4 {what}: {message}")]
    Container {
        /// Writing or reading.
        what: &'static str,
        /// The muxer's or demuxer's message.
        message: String,
    },
}

/// Result of a video operation.
pub type Result<T> = std::result::Result<T, Error>;

fn codec(what: &'static str) -> impl Fn(openh264::Error) -> Error {
    move |e| Error::Codec {
        what,
        message: e.to_string(),
    }
}

/// A finished MP4, in memory (write it whole: `mhi_data::write_atomic`).
#[derive(Debug, Clone)]
pub struct Video {
    /// The file's bytes.
    pub bytes: Vec<u8>,
    /// Frames written.
    pub frames: usize,
    /// Frame size in pixels.
    pub width: u32,
    /// See [`Video::width`].
    pub height: u32,
    /// Frames per second.
    pub fps: f64,
}

impl Video {
    /// How long it plays, in seconds.
    pub fn seconds(&self) -> f64 {
        self.frames as f64 / self.fps
    }
}

/// An H.264 MP4 being written, frame by frame (see the crate's documentation).
pub struct Mp4Encoder {
    encoder: Encoder,
    muxer: Muxer<Vec<u8>>,
    width: u32,
    height: u32,
    fps: f64,
    frames: usize,
}

impl std::fmt::Debug for Mp4Encoder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Mp4Encoder")
            .field("width", &self.width)
            .field("height", &self.height)
            .field("fps", &self.fps)
            .field("frames", &self.frames)
            .finish_non_exhaustive()
    }
}

impl Mp4Encoder {
    /// A video of `width × height` frames at `fps` frames per second. H.264's 4:2:0 colour
    /// needs even sides.
    ///
    /// # Errors
    /// [`Error::Invalid`] for an odd or zero side, a side above [`MAX_SIDE`], or a frame rate
    /// that is not a finite number in (0, 240].
    pub fn new(width: u32, height: u32, fps: f64) -> Result<Self> {
        if width == 0 || height == 0 || width % 2 == 1 || height % 2 == 1 {
            return Err(Error::Invalid(format!(
                "a {width}x{height} video: H.264's 4:2:0 colour needs both sides even and above zero"
            )));
        }
        if width > MAX_SIDE || height > MAX_SIDE {
            return Err(Error::Invalid(format!(
                "a {width}x{height} video: at most {MAX_SIDE} pixels a side"
            )));
        }
        if !(fps.is_finite() && fps > 0.0 && fps <= 240.0) {
            return Err(Error::Invalid(format!(
                "{fps} frames per second: a video plays at a finite rate in (0, 240]"
            )));
        }
        // Quality first: a fixed QP range near-transparent for rendered views (decoded frames
        // stay above 35 dB PSNR of the frames given; see the tests), every 2 s an IDR frame so a
        // player can seek. Frame skipping is on only because quality mode without it prints a
        // warning on every video; the bitrate ceiling is far above what QP 8 needs, and a
        // skipped frame would come out empty, which `push` refuses.
        let config = EncoderConfig::new()
            .rate_control_mode(RateControlMode::Quality)
            .bitrate(BitRate::from_bps(
                (f64::from(width * height) * fps * 4.0).clamp(2e5, 2e9) as u32,
            ))
            .max_frame_rate(FrameRate::from_hz(fps as f32))
            .qp(QpRange::new(8, 20))
            .complexity(Complexity::High)
            .skip_frames(true)
            .intra_frame_period(IntraFramePeriod::from_num_frames(
                (2.0 * fps).round().max(1.0) as u32,
            ))
            .vui(VuiConfig::bt601());
        let encoder = Encoder::with_api_config(OpenH264API::from_source(), config)
            .map_err(codec("encoder"))?;
        let muxer = MuxerBuilder::new(Vec::new())
            .video(VideoCodec::H264, width, height, fps)
            .with_fast_start(true)
            .with_metadata(Metadata::new().with_title(TITLE))
            .build()
            .map_err(|e| Error::Container {
                what: "writer",
                message: e.to_string(),
            })?;
        Ok(Self {
            encoder,
            muxer,
            width,
            height,
            fps,
            frames: 0,
        })
    }

    /// Encode one frame.
    ///
    /// # Errors
    /// [`Error::Invalid`] for a frame of another size; [`Error::Codec`] or
    /// [`Error::Container`] if the encoder or muxer fails.
    pub fn push(&mut self, frame: &RgbImage) -> Result<()> {
        if frame.dimensions() != (self.width, self.height) {
            return Err(Error::Invalid(format!(
                "frame {} is {}x{}; the video is {}x{}",
                self.frames + 1,
                frame.width(),
                frame.height(),
                self.width,
                self.height
            )));
        }
        let yuv = rgb_to_yuv420(frame);
        let stream = self.encoder.encode(&yuv).map_err(codec("encoding"))?;
        let keyframe = matches!(stream.frame_type(), FrameType::IDR | FrameType::I);
        let bytes = stream.to_vec();
        if bytes.is_empty() {
            return Err(Error::Codec {
                what: "encoding",
                message: format!("frame {} came out empty", self.frames + 1),
            });
        }
        let pts = self.frames as f64 / self.fps;
        self.muxer
            .write_video(pts, &bytes, keyframe)
            .map_err(|e| Error::Container {
                what: "writer",
                message: e.to_string(),
            })?;
        self.frames += 1;
        Ok(())
    }

    /// Frames pushed so far.
    pub fn frames(&self) -> usize {
        self.frames
    }

    /// Finish the file.
    ///
    /// # Errors
    /// [`Error::Invalid`] when no frame was pushed; [`Error::Container`] if the muxer fails.
    pub fn finish(mut self) -> Result<Video> {
        if self.frames == 0 {
            return Err(Error::Invalid(
                "a video needs at least one frame".to_string(),
            ));
        }
        self.muxer.finish_in_place().map_err(|e| Error::Container {
            what: "writer",
            message: e.to_string(),
        })?;
        Ok(Video {
            bytes: self.muxer.into_writer(),
            frames: self.frames,
            width: self.width,
            height: self.height,
            fps: self.fps,
        })
    }
}

/// An MP4's first H.264 track, decoded.
#[derive(Debug, Clone)]
pub struct Decoded {
    /// Frame size in pixels, as the track header says.
    pub width: u32,
    /// See [`Decoded::width`].
    pub height: u32,
    /// Frames per second, as the track's sample table says.
    pub fps: f64,
    /// Every frame, in presentation order (this crate writes no B-frames).
    pub frames: Vec<RgbImage>,
}

/// Read an MP4 and decode its first H.264 track to RGB frames.
///
/// # Errors
/// [`Error::Container`] for a file that is not an MP4 or holds no H.264 track;
/// [`Error::Codec`] for a frame that does not decode or decodes to another size.
pub fn decode_mp4(bytes: &[u8]) -> Result<Decoded> {
    let container = |e: mp4::Error| Error::Container {
        what: "reader",
        message: e.to_string(),
    };
    let mut reader =
        mp4::Mp4Reader::read_header(Cursor::new(bytes), bytes.len() as u64).map_err(container)?;
    let track = reader
        .tracks()
        .values()
        .filter(|t| t.media_type().is_ok_and(|m| m == mp4::MediaType::H264))
        .min_by_key(|t| t.track_id())
        .ok_or_else(|| Error::Container {
            what: "reader",
            message: "no H.264 video track".to_string(),
        })?;
    let (id, width, height, fps) = (
        track.track_id(),
        u32::from(track.width()),
        u32::from(track.height()),
        track.frame_rate(),
    );
    // The parameter sets live in the avcC box; each sample is length-prefixed NAL units.
    let mut annex_b = Vec::new();
    for ps in [
        track.sequence_parameter_set().map_err(container)?,
        track.picture_parameter_set().map_err(container)?,
    ] {
        annex_b.extend_from_slice(&[0, 0, 0, 1]);
        annex_b.extend_from_slice(ps);
    }
    let count = reader.sample_count(id).map_err(container)?;
    let mut decoder = Decoder::with_api_config(OpenH264API::from_source(), DecoderConfig::new())
        .map_err(codec("decoder"))?;
    let mut frames = Vec::with_capacity(count as usize);
    for sample_id in 1..=count {
        let sample = reader
            .read_sample(id, sample_id)
            .map_err(container)?
            .ok_or_else(|| Error::Container {
                what: "reader",
                message: format!("sample {sample_id} of {count} is missing"),
            })?;
        let mut rest: &[u8] = &sample.bytes;
        while rest.len() >= 4 {
            let n = u32::from_be_bytes([rest[0], rest[1], rest[2], rest[3]]) as usize;
            if n == 0 || rest.len() < 4 + n {
                return Err(Error::Container {
                    what: "reader",
                    message: format!("sample {sample_id}: a NAL unit overruns the sample"),
                });
            }
            annex_b.extend_from_slice(&[0, 0, 0, 1]);
            annex_b.extend_from_slice(&rest[4..4 + n]);
            rest = &rest[4 + n..];
        }
        if let Some(yuv) = decoder.decode(&annex_b).map_err(codec("decoding"))? {
            frames.push(to_rgb(&yuv, width, height, sample_id)?);
        }
        annex_b.clear();
    }
    for yuv in decoder.flush_remaining().map_err(codec("decoding"))? {
        frames.push(to_rgb(&yuv, width, height, count)?);
    }
    Ok(Decoded {
        width,
        height,
        fps,
        frames,
    })
}

fn to_rgb(yuv: &DecodedYUV<'_>, width: u32, height: u32, sample: u32) -> Result<RgbImage> {
    let (w, h) = yuv.dimensions();
    if (w, h) != (width as usize, height as usize) {
        return Err(Error::Codec {
            what: "decoding",
            message: format!("sample {sample} decodes to {w}x{h}; the track says {width}x{height}"),
        });
    }
    Ok(yuv420_to_rgb(yuv))
}

// BT.601, limited range ("studio swing"): Y in [16, 235], Cb and Cr in [16, 240].
const KR: f32 = 0.299;
const KB: f32 = 0.114;

/// RGB to YUV 4:2:0 (BT.601, limited range), rounding to nearest; each chroma sample is the
/// mean of its 2 × 2 pixels (sited at their centre).
pub fn rgb_to_yuv420(frame: &RgbImage) -> YUVBuffer {
    let (w, h) = (frame.width() as usize, frame.height() as usize);
    let (cw, ch) = (w / 2, h / 2);
    let mut buf = vec![0u8; w * h + 2 * cw * ch];
    let (y_plane, chroma) = buf.split_at_mut(w * h);
    let (u_plane, v_plane) = chroma.split_at_mut(cw * ch);
    let px = frame.as_raw();
    let kg = 1.0 - KR - KB;
    let luma = |r: f32, g: f32, b: f32| KR * r + kg * g + KB * b;
    for (i, y) in y_plane.iter_mut().enumerate() {
        let p = &px[3 * i..3 * i + 3];
        let l = luma(f32::from(p[0]), f32::from(p[1]), f32::from(p[2]));
        *y = (16.0 + l * 219.0 / 255.0).round().clamp(0.0, 255.0) as u8;
    }
    for cy in 0..ch {
        for cx in 0..cw {
            let mut rgb = [0.0_f32; 3];
            for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                let i = 3 * ((2 * cy + dy) * w + 2 * cx + dx);
                for c in 0..3 {
                    rgb[c] += 0.25 * f32::from(px[i + c]);
                }
            }
            let l = luma(rgb[0], rgb[1], rgb[2]);
            let cb = (rgb[2] - l) / (2.0 * (1.0 - KB));
            let cr = (rgb[0] - l) / (2.0 * (1.0 - KR));
            let q = |c: f32| (128.0 + c * 224.0 / 255.0).round().clamp(0.0, 255.0) as u8;
            u_plane[cy * cw + cx] = q(cb);
            v_plane[cy * cw + cx] = q(cr);
        }
    }
    YUVBuffer::from_vec(buf, w, h)
}

/// YUV 4:2:0 (BT.601, limited range) to RGB, the chroma upsampled bilinearly from the centres
/// of its 2 × 2 blocks (as [`rgb_to_yuv420`] sites it), rounding to nearest.
pub fn yuv420_to_rgb(yuv: &impl YUVSource) -> RgbImage {
    let (w, h) = yuv.dimensions();
    let (sy, su, sv) = yuv.strides();
    let (cw, ch) = (w.div_ceil(2), h.div_ceil(2));
    let (yp, up, vp) = (yuv.y(), yuv.u(), yuv.v());
    let chroma = |plane: &[u8], stride: usize, x: usize, y: usize| -> f32 {
        // Chroma sample (i, j) sits at pixel (2i + 0.5, 2j + 0.5).
        let fx = ((x as f32 - 0.5) / 2.0).clamp(0.0, (cw - 1) as f32);
        let fy = ((y as f32 - 0.5) / 2.0).clamp(0.0, (ch - 1) as f32);
        let (x0, y0) = (fx.floor() as usize, fy.floor() as usize);
        let (x1, y1) = ((x0 + 1).min(cw - 1), (y0 + 1).min(ch - 1));
        let (ax, ay) = (fx - x0 as f32, fy - y0 as f32);
        let at = |i: usize, j: usize| f32::from(plane[j * stride + i]);
        (1.0 - ay) * ((1.0 - ax) * at(x0, y0) + ax * at(x1, y0))
            + ay * ((1.0 - ax) * at(x0, y1) + ax * at(x1, y1))
    };
    let kg = 1.0 - KR - KB;
    RgbImage::from_fn(w as u32, h as u32, |x, y| {
        let (x, y) = (x as usize, y as usize);
        let l = (f32::from(yp[y * sy + x]) - 16.0) * 255.0 / 219.0;
        let cb = (chroma(up, su, x, y) - 128.0) * 255.0 / 224.0;
        let cr = (chroma(vp, sv, x, y) - 128.0) * 255.0 / 224.0;
        let r = l + 2.0 * (1.0 - KR) * cr;
        let b = l + 2.0 * (1.0 - KB) * cb;
        let g = (l - KR * r - KB * b) / kg;
        image::Rgb([r, g, b].map(|v| v.round().clamp(0.0, 255.0) as u8))
    })
}
