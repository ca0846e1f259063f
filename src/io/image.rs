// SPDX-License-Identifier: MIT OR Apache-2.0
//! Image decoding and encoding, colour-space conversion and atomic file writes.
//!
//! All colour work inside decalbake is linear RGBA in `f32`. 8-bit images are taken as sRGB-encoded and
//! decoded with the exact sRGB transfer function; 16-bit PNGs likewise (the PNG convention), so 16-bit
//! inputs keep their precision end to end. Output is encoded back to sRGB at 8 or 16 bits.
//!
//! Decoding has limits, checked from the image's header before any pixel is decoded: at most
//! [`MAX_IMAGE_SIDE`] pixels a side and [`MAX_IMAGE_PIXELS`] pixels in all (8192², as large as
//! the largest texture an 8K bake uses; 1 GiB as linear RGBA), and the decoder's own buffers within
//! [`DECODER_MAX_ALLOC`]. Without them a JPEG of a few hundred bytes whose header claims 16384²
//! decodes (the decoder fills what is missing) into 4 GiB (found by `decalbake fuzz`); within them
//! a small file can still claim 8192² and cost about 1.5 GiB and a second and a half, which is what
//! an 8K texture costs.

use crate::error::{Error, Result};
use std::path::Path;

/// Most pixels a decoded image may have on a side.
pub const MAX_IMAGE_SIDE: u32 = 16384;
/// Most pixels a decoded image may have: 2²⁶ (8192 × 8192), 1 GiB as linear RGBA.
pub const MAX_IMAGE_PIXELS: u64 = 1 << 26;
/// Most bytes the image decoder may allocate (an 8192² image at 16 bits per RGBA channel).
pub const DECODER_MAX_ALLOC: u64 = 512 << 20;

/// An image of `width` × `height` within decalbake's limits, or what is wrong.
pub fn check_image_size(width: u32, height: u32) -> std::result::Result<(), String> {
    let pixels = width as u64 * height as u64;
    if width > MAX_IMAGE_SIDE || height > MAX_IMAGE_SIDE || pixels > MAX_IMAGE_PIXELS {
        return Err(format!(
            "{width} x {height} pixels is above decalbake's image limits ({MAX_IMAGE_SIDE} pixels a side, {MAX_IMAGE_PIXELS} pixels in all, e.g. 8192 x 8192); downscale it"
        ));
    }
    Ok(())
}

/// A straight-alpha, linear-light RGBA image.
#[derive(Debug, Clone, PartialEq)]
pub struct LinearImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Row-major pixels, top row first.
    pub pixels: Vec<[f32; 4]>,
}

/// sRGB transfer function, decode (IEC 61966-2-1).
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// sRGB transfer function, encode (IEC 61966-2-1).
pub fn linear_to_srgb(c: f32) -> f32 {
    let c = c.clamp(0.0, 1.0);
    if c <= 0.003_130_8 {
        c * 12.92
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

impl LinearImage {
    /// Bilinear sample at (u, v) in [0, 1]² (texel centres at half-integers), with clamp-to-edge or,
    /// when `repeat`, wrapping (glTF's default sampler). The CPU twins' one image sampler.
    pub fn bilinear(&self, u: f32, v: f32, repeat: bool) -> [f32; 4] {
        let x = u * self.width as f32 - 0.5;
        let y = v * self.height as f32 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let at = |xi: f32, yi: f32| {
            let (w, h) = (self.width as i64, self.height as i64);
            let (xi, yi) = if repeat {
                ((xi as i64).rem_euclid(w), (yi as i64).rem_euclid(h))
            } else {
                ((xi as i64).clamp(0, w - 1), (yi as i64).clamp(0, h - 1))
            };
            self.pixels[(yi * w + xi) as usize]
        };
        let (a, b, c, d) = (
            at(x0, y0),
            at(x0 + 1.0, y0),
            at(x0, y0 + 1.0),
            at(x0 + 1.0, y0 + 1.0),
        );
        std::array::from_fn(|k| {
            (a[k] * (1.0 - fx) + b[k] * fx) * (1.0 - fy) + (c[k] * (1.0 - fx) + d[k] * fx) * fy
        })
    }

    /// A `width`×`height` image filled with one colour.
    pub fn solid(width: u32, height: u32, rgba: [f32; 4]) -> Self {
        Self {
            width,
            height,
            pixels: vec![rgba; (width * height) as usize],
        }
    }

    /// Decodes an image file (PNG or JPEG, 8 or 16 bit). Colour channels are sRGB-decoded, alpha is
    /// kept linear.
    pub fn load(path: &Path) -> Result<Self> {
        let bytes = std::fs::read(path).map_err(|source| Error::Io {
            path: path.to_path_buf(),
            action: "reading the image",
            source,
        })?;
        Self::decode(&bytes).map_err(|detail| Error::Image {
            path: path.to_path_buf(),
            action: "decoding",
            detail: format!("{detail}; decalbake reads PNG and JPEG images"),
        })
    }

    /// Decodes encoded image bytes (PNG or JPEG) within the limits of the module doc (checked from
    /// the header, before decoding).
    pub fn decode(bytes: &[u8]) -> std::result::Result<Self, String> {
        // The image crate also reads OpenEXR (for our EXR output); an image read here is sRGB
        // colour, which a linear EXR is not.
        match image::guess_format(bytes) {
            Ok(image::ImageFormat::Png | image::ImageFormat::Jpeg) => {}
            Ok(other) => return Err(format!("{other:?} images are not supported")),
            Err(e) => return Err(e.to_string()),
        }
        let reader = || {
            let mut r = image::ImageReader::new(std::io::Cursor::new(bytes))
                .with_guessed_format()
                .map_err(|e| e.to_string())?;
            let mut limits = image::Limits::default();
            limits.max_image_width = Some(MAX_IMAGE_SIDE);
            limits.max_image_height = Some(MAX_IMAGE_SIDE);
            limits.max_alloc = Some(DECODER_MAX_ALLOC);
            r.limits(limits);
            Ok::<_, String>(r)
        };
        let limited = |e: image::ImageError| {
            match e {
            image::ImageError::Limits(_) => format!(
                "{e} (decalbake decodes images of at most {MAX_IMAGE_SIDE} pixels a side, {MAX_IMAGE_PIXELS} pixels in all, with {} MiB for the decoder); downscale it",
                DECODER_MAX_ALLOC >> 20
            ),
            e => e.to_string(),
        }
        };
        let (w, h) = reader()?.into_dimensions().map_err(limited)?;
        check_image_size(w, h)?;
        let img = reader()?.decode().map_err(limited)?;
        let (width, height) = (img.width(), img.height());
        let pixels = if img.color().bytes_per_pixel() / img.color().channel_count().max(1) >= 2 {
            // `into_` keeps the decoder's buffer when it is RGBA already (no second copy).
            let buf = img.into_rgba16();
            buf.pixels()
                .map(|p| {
                    let f = |c: u16| c as f32 / 65535.0;
                    [
                        srgb_to_linear(f(p[0])),
                        srgb_to_linear(f(p[1])),
                        srgb_to_linear(f(p[2])),
                        f(p[3]),
                    ]
                })
                .collect()
        } else {
            let buf = img.into_rgba8();
            let lut: Vec<f32> = (0..256).map(|c| srgb_to_linear(c as f32 / 255.0)).collect();
            buf.pixels()
                .map(|p| {
                    [
                        lut[p[0] as usize],
                        lut[p[1] as usize],
                        lut[p[2] as usize],
                        p[3] as f32 / 255.0,
                    ]
                })
                .collect()
        };
        Ok(Self {
            width,
            height,
            pixels,
        })
    }

    /// Converts image data decoded by the `gltf` crate. `srgb` says whether colour channels are
    /// sRGB-encoded (base-colour textures are).
    pub fn from_gltf(data: &gltf::image::Data, srgb: bool) -> std::result::Result<Self, String> {
        use gltf::image::Format as F;
        let dec = |c: f32| if srgb { srgb_to_linear(c) } else { c };
        let (ch, bytes_per_ch): (usize, usize) = match data.format {
            F::R8 => (1, 1),
            F::R8G8 => (2, 1),
            F::R8G8B8 => (3, 1),
            F::R8G8B8A8 => (4, 1),
            F::R16 => (1, 2),
            F::R16G16 => (2, 2),
            F::R16G16B16 => (3, 2),
            F::R16G16B16A16 => (4, 2),
            other => return Err(format!("unsupported pixel format {other:?}")),
        };
        check_image_size(data.width, data.height)?;
        let n = data.width as usize * data.height as usize;
        if data.pixels.len() < n * ch * bytes_per_ch {
            return Err("pixel data is shorter than width × height".into());
        }
        let read = |i: usize| -> f32 {
            if bytes_per_ch == 1 {
                data.pixels[i] as f32 / 255.0
            } else {
                u16::from_ne_bytes([data.pixels[2 * i], data.pixels[2 * i + 1]]) as f32 / 65535.0
            }
        };
        let pixels = (0..n)
            .map(|p| {
                let c = |k: usize| read(p * ch + k);
                match ch {
                    1 => [dec(c(0)), dec(c(0)), dec(c(0)), 1.0],
                    2 => [dec(c(0)), dec(c(0)), dec(c(0)), c(1)],
                    3 => [dec(c(0)), dec(c(1)), dec(c(2)), 1.0],
                    _ => [dec(c(0)), dec(c(1)), dec(c(2)), c(3)],
                }
            })
            .collect();
        Ok(Self {
            width: data.width,
            height: data.height,
            pixels,
        })
    }

    /// Encodes to PNG bytes, sRGB, 8 or 16 bits per channel.
    pub fn encode_png(&self, bit_depth: u8) -> Vec<u8> {
        png_bytes(self.width, self.height, bit_depth, &self.to_srgb(bit_depth))
    }

    /// sRGB-encoded RGBA values at `bit_depth` (0..=255 or 0..=65535); alpha stays linear.
    pub fn to_srgb(&self, bit_depth: u8) -> Vec<u16> {
        let max = if bit_depth == 16 { 65535.0 } else { 255.0 };
        let mut raw = Vec::with_capacity(self.pixels.len() * 4);
        for p in &self.pixels {
            for (k, c) in p.iter().enumerate() {
                let e = if k < 3 {
                    linear_to_srgb(*c)
                } else {
                    c.clamp(0.0, 1.0)
                };
                raw.push((e * max).round() as u16);
            }
        }
        raw
    }

    /// sRGB-encoded RGBA8 bytes.
    pub fn to_srgb8(&self) -> Vec<u8> {
        self.to_srgb(8).into_iter().map(|v| v as u8).collect()
    }

    /// Premultiplied-alpha mip chain (level 0 first), each level a 2×2 box filter of the previous,
    /// down to 1×1. Premultiplying before filtering keeps transparent texels from darkening edges.
    pub fn premultiplied_mips(&self) -> Vec<LinearImage> {
        let mut level = LinearImage {
            width: self.width,
            height: self.height,
            pixels: self
                .pixels
                .iter()
                .map(|p| [p[0] * p[3], p[1] * p[3], p[2] * p[3], p[3]])
                .collect(),
        };
        let mut out = Vec::new();
        loop {
            let (w, h) = (level.width, level.height);
            let next_w = (w / 2).max(1);
            let next_h = (h / 2).max(1);
            let done = w == 1 && h == 1;
            let mut next = LinearImage::solid(next_w, next_h, [0.0; 4]);
            if !done {
                for y in 0..next_h {
                    for x in 0..next_w {
                        let mut acc = [0.0f32; 4];
                        let xs = [(2 * x).min(w - 1), (2 * x + 1).min(w - 1)];
                        let ys = [(2 * y).min(h - 1), (2 * y + 1).min(h - 1)];
                        for sy in ys {
                            for sx in xs {
                                let p = level.pixels[(sy * w + sx) as usize];
                                for k in 0..4 {
                                    acc[k] += 0.25 * p[k];
                                }
                            }
                        }
                        next.pixels[(y * next_w + x) as usize] = acc;
                    }
                }
            }
            out.push(level);
            if done {
                break;
            }
            level = next;
        }
        out
    }
}

/// How hard a PNG is compressed (`output.compression`). Both keep every sample exactly.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PngCompression {
    /// Bands of rows deflated on every core by `fdeflate` (`io/png_bands.rs`): the default.
    #[default]
    Fast,
    /// The smallest file of a few encodings (the `png` crate's strongest deflate with adaptive,
    /// no or up filters, and the fast one): never larger than `Fast`, 10-30 times its encoding
    /// time. Which wins depends on the image (measured on the demo's textures: none for Spot's
    /// colour and the knight's ORM, up for the knight's colour, fast for a small noisy bake). A
    /// texture streamed band by band (`output/stream.rs`) is never held whole, so it gets one
    /// encoding, the strongest deflate with adaptive filters.
    Small,
}

/// One way of encoding a PNG's image data.
#[derive(Clone, Copy, Debug)]
enum Encoding {
    /// Independent bands on every core ([`super::png_bands`]).
    Bands,
    /// The `png` crate's stream writer at a deflate level, with a filter.
    Deflate(png::Compression, png::Filter),
}

impl PngCompression {
    /// The one encoding of a PNG written row by row ([`png_rows`]).
    fn encoding(self) -> Encoding {
        match self {
            PngCompression::Fast => Encoding::Bands,
            PngCompression::Small => {
                Encoding::Deflate(png::Compression::High, png::Filter::Adaptive)
            }
        }
    }
}

/// The encodings `PngCompression::Small` tries on a PNG held whole, the fast one first.
const SMALL_TRIES: [Encoding; 4] = [
    Encoding::Bands,
    Encoding::Deflate(png::Compression::High, png::Filter::Adaptive),
    Encoding::Deflate(png::Compression::High, png::Filter::NoFilter),
    Encoding::Deflate(png::Compression::High, png::Filter::Up),
];

/// PNG bytes of RGBA samples already encoded at `bit_depth` (8: 0..=255, 16: 0..=65535), written
/// through [`png_rows`], so that a texture streamed band by band and one encoded whole are the
/// same bytes.
///
/// # Panics
///
/// When `samples` does not hold `width × height × 4` samples (a caller's mistake: every sample
/// count the engine hands it is checked where the texture is made).
pub fn png_bytes(width: u32, height: u32, bit_depth: u8, samples: &[u16]) -> Vec<u8> {
    png_bytes_with(width, height, bit_depth, samples, PngCompression::Fast)
}

/// [`png_bytes`] at a chosen compression.
pub fn png_bytes_with(
    width: u32,
    height: u32,
    bit_depth: u8,
    samples: &[u16],
    compression: PngCompression,
) -> Vec<u8> {
    let tries = match compression {
        PngCompression::Fast => &SMALL_TRIES[..1],
        PngCompression::Small => &SMALL_TRIES[..],
    };
    use rayon::prelude::*;
    let encoded: Vec<Vec<u8>> = tries
        .par_iter()
        .map(|&encoding| encode_png(width, height, (bit_depth, encoding), samples))
        .collect();
    // The first of the smallest, in the tries' order: the same file on every run, and the fast
    // encoding where nothing beats it.
    encoded
        .into_iter()
        .reduce(|best, e| if e.len() < best.len() { e } else { best })
        .expect("at least one encoding")
}

/// One encoding of a PNG held whole, through [`png_rows_at`].
fn encode_png(width: u32, height: u32, depth: (u8, Encoding), samples: &[u16]) -> Vec<u8> {
    let mut out = Vec::new();
    png_rows_at(
        &mut out,
        [width, height],
        depth,
        Path::new("memory"),
        |png| {
            png.write_texels(samples).map_err(|source| Error::Io {
                path: "memory".into(),
                action: "writing",
                source,
            })
        },
    )
    .expect("PNG encoding into memory cannot fail for a well-formed buffer");
    out
}

/// Writes an RGBA PNG (8 or 16 bits) to `out` a few rows at a time: `fill` hands it every row, top
/// first, through [`PngRows::write_texels`] (a tiled bake streams its texture this way,
/// `output/stream.rs`). `Fast` deflates bands of rows on every core (`io/png_bands.rs`), `Small`
/// goes through the `png` crate's stream writer with its strongest deflate and adaptive filters;
/// both write IDAT chunks of [`PNG_CHUNK`] bytes. `fill`'s error, or the first write's (as
/// writing `path`), is returned; the image is complete only when this returns `Ok`.
pub fn png_rows<W: std::io::Write, T>(
    out: W,
    size: [u32; 2],
    (depth, compression): (u8, PngCompression),
    path: &Path,
    fill: impl FnOnce(&mut PngRows<'_, W>) -> Result<T>,
) -> Result<T> {
    png_rows_at(out, size, (depth, compression.encoding()), path, fill)
}

/// [`png_rows`] in a given encoding.
fn png_rows_at<W: std::io::Write, T>(
    out: W,
    [width, height]: [u32; 2],
    (depth, encoding): (u8, Encoding),
    path: &Path,
    fill: impl FnOnce(&mut PngRows<'_, W>) -> Result<T>,
) -> Result<T> {
    let io = |e: png::EncodingError| Error::Io {
        path: path.to_path_buf(),
        action: "writing",
        source: std::io::Error::other(e),
    };
    let mut enc = png::Encoder::new(out, width, height);
    enc.set_color(png::ColorType::Rgba);
    enc.set_depth(match depth {
        16 => png::BitDepth::Sixteen,
        _ => png::BitDepth::Eight,
    });
    if let Encoding::Deflate(level, filter) = encoding {
        enc.set_compression(level);
        enc.set_filter(filter);
    }
    let mut writer = enc.write_header().map_err(io)?;
    let t = match encoding {
        Encoding::Deflate(..) => {
            let mut rows = PngRows {
                sink: Sink::Stream(writer.stream_writer_with_size(PNG_CHUNK).map_err(io)?),
                depth,
                row: Vec::new(),
            };
            let t = fill(&mut rows)?;
            if let Sink::Stream(s) = rows.sink {
                s.finish().map_err(io)?;
            }
            t
        }
        Encoding::Bands => {
            let mut rows = PngRows {
                sink: Sink::Bands(BandSink::new(&mut writer, [width, height], depth)),
                depth,
                row: Vec::new(),
            };
            let t = fill(&mut rows)?;
            if let Sink::Bands(b) = rows.sink {
                b.finish().map_err(|source| Error::Io {
                    path: path.to_path_buf(),
                    action: "writing",
                    source,
                })?;
            }
            t
        }
    };
    writer.finish().map_err(io)?;
    Ok(t)
}

/// The rows of a PNG being written ([`png_rows`]).
pub struct PngRows<'a, W: std::io::Write> {
    sink: Sink<'a, W>,
    depth: u8,
    row: Vec<u8>,
}

/// Where [`PngRows`] sends its rows.
enum Sink<'a, W: std::io::Write> {
    Stream(png::StreamWriter<'a, W>),
    Bands(BandSink<'a, W>),
}

/// The bytes of one IDAT chunk of the PNGs the engine writes.
pub const PNG_CHUNK: usize = 1 << 20;

impl<W: std::io::Write> PngRows<'_, W> {
    /// Appends texels (4 samples each, whole rows or not), top row first.
    pub fn write_texels(&mut self, samples: &[u16]) -> std::io::Result<()> {
        use std::io::Write;
        match &mut self.sink {
            Sink::Bands(b) => b.write_samples(samples),
            Sink::Stream(writer) => {
                for part in samples.chunks(1 << 16) {
                    self.row.clear();
                    if self.depth == 16 {
                        self.row.extend(part.iter().flat_map(|v| v.to_be_bytes()));
                    } else {
                        self.row.extend(part.iter().map(|v| *v as u8));
                    }
                    writer.write_all(&self.row)?;
                }
                Ok(())
            }
        }
    }
}

/// The fast encoding's writer: samples are held until a band of rows is complete; complete
/// bands are encoded on every core (a few per core at a time, so the raw rows are never all
/// held) and their deflate output joined into IDAT chunks of [`PNG_CHUNK`] bytes.
struct BandSink<'a, W: std::io::Write> {
    writer: &'a mut png::Writer<W>,
    depth: u8,
    /// Samples in a row, and in a band.
    row_samples: usize,
    band_samples: usize,
    /// Samples of a band not yet complete.
    pending: Vec<u16>,
    /// The last row encoded, as bytes (zeros before the first).
    above: Vec<u8>,
    /// Joined deflate bytes not yet written, and the Adler-32 of the filtered bytes so far.
    idat: Vec<u8>,
    adler: u32,
    /// Samples the image has, and samples handed over so far.
    expected: usize,
    written: usize,
}

impl<'a, W: std::io::Write> BandSink<'a, W> {
    fn new(writer: &'a mut png::Writer<W>, [width, height]: [u32; 2], depth: u8) -> Self {
        let row_samples = width as usize * 4;
        let row_bytes = row_samples * if depth == 16 { 2 } else { 1 };
        let band_samples = super::png_bands::band_rows(row_bytes) * row_samples;
        BandSink {
            writer,
            depth,
            row_samples,
            band_samples,
            pending: Vec::new(),
            above: vec![0; row_bytes],
            idat: super::png_bands::ZLIB_HEADER.to_vec(),
            adler: 1,
            expected: row_samples * height as usize,
            written: 0,
        }
    }

    /// The error of a writer handed more or fewer samples than the image has.
    fn wrong_count(&self, written: usize) -> std::io::Error {
        std::io::Error::other(format!(
            "the PNG writer was handed {written} samples for an image of {}",
            self.expected
        ))
    }

    /// Encodes every complete band of `samples` (after what is pending) and keeps the rest.
    fn write_samples(&mut self, mut samples: &[u16]) -> std::io::Result<()> {
        if self.written + samples.len() > self.expected {
            return Err(self.wrong_count(self.written + samples.len()));
        }
        self.written += samples.len();
        if !self.pending.is_empty() {
            let take = (self.band_samples - self.pending.len()).min(samples.len());
            self.pending.extend_from_slice(&samples[..take]);
            samples = &samples[take..];
            if self.pending.len() < self.band_samples {
                return Ok(());
            }
            let band = std::mem::take(&mut self.pending);
            self.encode(&band)?;
        }
        // A few bands per core at a time: the count only sets the pace, never the bytes.
        let window = self.band_samples * 2 * rayon::current_num_threads().max(1);
        let whole = samples.len() / self.band_samples * self.band_samples;
        for part in samples[..whole].chunks(window) {
            self.encode(part)?;
        }
        self.pending.extend_from_slice(&samples[whole..]);
        Ok(())
    }

    /// Encodes `samples` (whole bands, the last possibly short) in parallel and joins them.
    fn encode(&mut self, samples: &[u16]) -> std::io::Result<()> {
        use rayon::prelude::*;
        let (depth, row) = (self.depth, self.row_samples);
        let bytes = |s: &[u16]| -> Vec<u8> {
            if depth == 16 {
                s.iter().flat_map(|v| v.to_be_bytes()).collect()
            } else {
                s.iter().map(|v| *v as u8).collect()
            }
        };
        let bpp = if depth == 16 { 8 } else { 4 };
        let row_bytes = self.above.len();
        let above = &self.above;
        let bands: Vec<super::png_bands::Band> = samples
            .par_chunks(self.band_samples)
            .enumerate()
            .map(|(i, band)| {
                let start = i * self.band_samples;
                let prev = match start {
                    0 => above.clone(),
                    _ => bytes(&samples[start - row..start]),
                };
                super::png_bands::encode_band(bpp, &prev, &bytes(band), row_bytes)
            })
            .collect();
        self.above = bytes(&samples[samples.len() - row..]);
        for band in bands {
            self.adler = super::png_bands::adler_combine(self.adler, band.adler, band.len);
            self.idat.extend_from_slice(&band.deflate);
            self.flush_chunks(false)?;
        }
        Ok(())
    }

    /// Writes the IDAT chunks that are full (or, at the end, what is left).
    fn flush_chunks(&mut self, end: bool) -> std::io::Result<()> {
        let full = if end {
            self.idat.len()
        } else {
            self.idat.len() / PNG_CHUNK * PNG_CHUNK
        };
        for chunk in self.idat[..full].chunks(PNG_CHUNK) {
            self.writer
                .write_chunk(png::chunk::IDAT, chunk)
                .map_err(std::io::Error::other)?;
        }
        self.idat.drain(..full);
        Ok(())
    }

    /// Encodes the last (short) band, closes the stream and writes what is left.
    fn finish(mut self) -> std::io::Result<()> {
        if self.written != self.expected {
            return Err(self.wrong_count(self.written));
        }
        if !self.pending.is_empty() {
            let band = std::mem::take(&mut self.pending);
            self.encode(&band)?;
        }
        let end = super::png_bands::stream_end(self.adler);
        self.idat.extend_from_slice(&end);
        self.flush_chunks(true)
    }
}

/// Writes an OpenEXR image (linear RGBA, 32-bit float channels; RLE-compressed 64 × 64 tiles, as
/// the `image` crate's encoder writes it) to `out` a band of rows at a time: `fill` hands it every
/// row, top first, through [`ExrRows::write_rows`], in bands whose first rows are multiples of 64
/// (a tiled bake's bands, `output/stream.rs`). `fill`'s error, or the first write's (as writing
/// `path`), is returned; the file is complete only when this returns `Ok`.
pub fn exr_rows<W: std::io::Write + std::io::Seek, T>(
    out: W,
    [width, height]: [u32; 2],
    path: &Path,
    fill: impl FnOnce(&mut ExrRows<'_, W>) -> Result<T>,
) -> Result<T> {
    use exr::meta::attribute::{ChannelDescription, SampleType, Text};
    use exr::prelude::SmallVec;
    let channels: SmallVec<[ChannelDescription; 5]> = ["A", "B", "G", "R"]
        .into_iter()
        .map(|c| ChannelDescription::named(c, SampleType::F32))
        .collect();
    let size = (width as usize, height as usize);
    let mut header = exr::meta::header::Header::new(Text::new_or_panic("rgba"), size, channels);
    header.own_attributes = Default::default();
    let headers: exr::meta::Headers = std::iter::once(header).collect();
    let mut outcome: Option<Result<T>> = None;
    let written = exr::block::write(out, headers, true, |meta, writer| {
        let blocks = exr::block::enumerate_ordered_header_block_indices(&meta.headers).collect();
        let mut rows = ExrRows {
            writer,
            headers: &meta.headers,
            blocks,
            next: 0,
            width: width as usize,
        };
        let r = fill(&mut rows);
        let done = rows.next == rows.blocks.len();
        let failed = r.is_err();
        outcome = Some(r);
        match (failed, done) {
            (false, true) => Ok(()),
            _ => Err(exr::error::Error::Aborted),
        }
    });
    let io = |e: exr::error::Error| Error::Io {
        path: path.to_path_buf(),
        action: "writing",
        source: std::io::Error::other(e),
    };
    match (outcome, written) {
        (Some(Err(e)), _) => Err(e),
        (Some(Ok(t)), Ok(())) => Ok(t),
        (_, Err(exr::error::Error::Aborted)) => Err(Error::Io {
            path: path.to_path_buf(),
            action: "writing",
            source: std::io::Error::other(
                "the bake handed the EXR writer fewer rows than the image has",
            ),
        }),
        (_, Err(e)) => Err(io(e)),
        (None, Ok(())) => unreachable!("the block writer runs its closure"),
    }
}

/// The blocks of an OpenEXR image being written ([`exr_rows`]).
pub struct ExrRows<'a, W> {
    writer: &'a mut exr::block::writer::ChunkWriter<W>,
    headers: &'a [exr::meta::header::Header],
    blocks: Vec<(usize, exr::block::BlockIndex)>,
    next: usize,
    width: usize,
}

impl<W: std::io::Write + std::io::Seek> ExrRows<'_, W> {
    /// Writes every block that lies within the rows `y0..` held by `linear` (RGBA f32, 4 values a
    /// texel, whole rows of the image). The blocks are gathered and compressed on every core, a
    /// few per core at a time (so the compressed blocks are never all held), and written in the
    /// file's order: the same bytes as one at a time.
    pub fn write_rows(&mut self, y0: u32, linear: &[f32]) -> exr::error::UnitResult {
        let rows = linear.len() / 4 / self.width;
        let end = y0 as usize + rows;
        let ready = self.blocks[self.next..]
            .iter()
            .take_while(|(_, b)| b.pixel_position.y() + b.pixel_size.y() <= end)
            .count();
        let (width, headers) = (self.width, self.headers);
        let window = 4 * rayon::current_num_threads().max(1);
        let blocks = self.blocks[self.next..self.next + ready].to_vec();
        for part in blocks.chunks(window) {
            self.write_blocks(part, y0, linear, (width, headers))?;
        }
        Ok(())
    }

    /// Compresses `blocks` (within the rows `y0..` held by `linear`) in parallel and writes them
    /// in order.
    fn write_blocks(
        &mut self,
        blocks: &[(usize, exr::block::BlockIndex)],
        y0: u32,
        linear: &[f32],
        (width, headers): (usize, &[exr::meta::header::Header]),
    ) -> exr::error::UnitResult {
        use exr::block::writer::ChunksWriter;
        use rayon::prelude::*;
        let chunks: Vec<_> = blocks
            .par_iter()
            .map(|&(index, block)| {
                let (p, s) = (block.pixel_position, block.pixel_size);
                let mut data = Vec::with_capacity(s.x() * s.y() * 16);
                for y in p.y()..p.y() + s.y() {
                    let row = &linear[(y - y0 as usize) * width * 4..][..width * 4];
                    // Channels in the file's (alphabetical) order: A, B, G, R.
                    for c in [3, 2, 1, 0] {
                        for x in p.x()..p.x() + s.x() {
                            data.extend_from_slice(&row[x * 4 + c].to_ne_bytes());
                        }
                    }
                }
                let chunk = exr::block::UncompressedBlock { index: block, data }
                    .compress_to_chunk(headers)?;
                Ok((index, chunk))
            })
            .collect::<exr::error::Result<_>>()?;
        for (index, chunk) in chunks {
            self.writer.write_chunk(index, chunk)?;
            self.next += 1;
        }
        Ok(())
    }
}

/// Writes `bytes` to `path` through a temporary file in the same directory and a rename, so a reader
/// never sees a half-written file and a failure leaves nothing behind.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let file_name = path
        .file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = dir.join(format!(".{file_name}.tmp-{}", std::process::id()));
    let io = |source| Error::Io {
        path: path.to_path_buf(),
        action: "writing",
        source,
    };
    if let Err(e) = write_durable(&tmp, bytes) {
        let _ = std::fs::remove_file(&tmp);
        return Err(io(e));
    }
    std::fs::rename(&tmp, path).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        io(e)
    })?;
    sync_dir(dir);
    Ok(())
}

/// Writes `bytes` to `path` and waits until they are on the disk (`File::sync_all`): a file
/// renamed into place afterwards is never seen empty or short after a crash or power loss, so
/// a batch that resumes from the outputs it finds never takes a torn file for a finished one.
pub fn write_durable(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    use std::io::Write;
    let mut f = std::fs::File::create(path)?;
    f.write_all(bytes)?;
    f.sync_all()
}

/// Makes the renames in `dir` durable (the directory's entries synced), where the platform can
/// open a directory; best effort: a failure here leaves the files written, only perhaps not yet
/// their names.
pub fn sync_dir(dir: &Path) {
    if let Ok(d) = std::fs::File::open(dir) {
        let _ = d.sync_all();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_round_trip_is_exact_at_8_bits() {
        for c in 0..=255u32 {
            let lin = srgb_to_linear(c as f32 / 255.0);
            let back = (linear_to_srgb(lin) * 255.0).round() as u32;
            assert_eq!(back, c);
        }
    }

    #[test]
    fn sixteen_bit_png_round_trips() {
        let mut img = LinearImage::solid(3, 2, [0.0; 4]);
        for (i, p) in img.pixels.iter_mut().enumerate() {
            *p = [i as f32 / 7.0, 0.25, 0.999, 0.5];
        }
        let back = LinearImage::decode(&img.encode_png(16)).unwrap();
        for (a, b) in img.pixels.iter().zip(&back.pixels) {
            for k in 0..4 {
                assert!((a[k] - b[k]).abs() < 1e-4, "{a:?} vs {b:?}");
            }
        }
    }

    /// Samples of several bands (varied content, so every filter comes up), at a bit depth.
    fn band_samples(width: u32, height: u32, depth: u8) -> Vec<u16> {
        let max = if depth == 16 { 65535 } else { 255 };
        let mut s = 7u32;
        (0..width * height * 4)
            .map(|i| {
                s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                let (x, y) = ((i / 4) % width, i / 4 / width);
                let v = match (y / 3) % 3 {
                    0 => x * 5 + y,
                    1 => s >> 20,
                    _ => 77,
                };
                (v % (max + 1)) as u16
            })
            .collect()
    }

    #[test]
    fn a_fast_png_handed_too_few_or_too_many_samples_is_an_error() {
        let mut samples = band_samples(8, 8, 8);
        samples.extend_from_slice(&[1, 2, 3, 4]);
        for n in [samples.len() - 8, samples.len()] {
            let mut out = Vec::new();
            let r = png_rows(
                &mut out,
                [8, 8],
                (8, PngCompression::Fast),
                Path::new("m"),
                |p| {
                    p.write_texels(&samples[..n]).map_err(|source| Error::Io {
                        path: "m".into(),
                        action: "writing",
                        source,
                    })
                },
            );
            let e = r.expect_err("a wrong sample count").to_string();
            assert!(e.contains("samples for an image of 256"), "{n}: {e}");
        }
    }

    #[test]
    fn fast_pngs_stream_in_any_pieces_and_decode_to_their_samples() {
        for depth in [8u8, 16] {
            let (w, h) = (300, 2700);
            let samples = band_samples(w, h, depth);
            let whole = png_bytes(w, h, depth, &samples);
            // Pieces that cut rows and bands anywhere give the same bytes.
            let mut streamed = Vec::new();
            png_rows(
                &mut streamed,
                [w, h],
                (depth, PngCompression::Fast),
                Path::new("m"),
                |p| {
                    for piece in samples.chunks(4 * 1237 + 8) {
                        p.write_texels(piece).unwrap();
                    }
                    Ok(())
                },
            )
            .unwrap();
            assert!(streamed == whole, "{depth}-bit: streamed bytes differ");
            let rows = super::super::png_bands::band_rows(w as usize * 4 * depth as usize / 8);
            assert!((h as usize).div_ceil(rows) >= 3, "several bands");
            let mut r = png::Decoder::new(std::io::Cursor::new(&whole))
                .read_info()
                .unwrap();
            let mut buf = vec![0; r.output_buffer_size().unwrap()];
            r.next_frame(&mut buf).unwrap();
            let back: Vec<u16> = match depth {
                16 => buf
                    .chunks_exact(2)
                    .map(|b| u16::from_be_bytes([b[0], b[1]]))
                    .collect(),
                _ => buf.iter().map(|&b| u16::from(b)).collect(),
            };
            assert!(back == samples, "{depth}-bit: decoded samples differ");
        }
    }

    #[test]
    fn mips_preserve_mean_premultiplied_colour() {
        let mut img = LinearImage::solid(4, 2, [1.0, 0.0, 0.0, 1.0]);
        img.pixels[0] = [0.0, 1.0, 0.0, 0.0];
        let mips = img.premultiplied_mips();
        assert_eq!(mips.len(), 3);
        let last = mips[2].pixels[0];
        // 7 of 8 texels are opaque red, one is transparent: mean premultiplied red = 7/8, alpha 7/8.
        assert!(
            (last[0] - 0.875).abs() < 1e-6
                && (last[3] - 0.875).abs() < 1e-6
                && last[1].abs() < 1e-6
        );
    }
}
