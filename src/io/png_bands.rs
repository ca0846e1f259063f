//! A PNG's image data encoded in independent bands of rows, on every core.
//!
//! The rows are cut into bands of [`band_rows`] rows (about 1 MiB of samples each, a number that
//! depends on the row width only, so the bytes never depend on the machine). Each band is
//! filtered (adaptive: per row the filter, of up, sub, average and Paeth, whose bytes have the
//! smallest sum of absolute values, as the `png` crate chooses) against the row above it, and
//! deflated on its own by `fdeflate` (the `png` crate's fast compressor, tuned for filtered
//! image data). The bands' deflate blocks are then joined into one zlib stream, as `mtpng`
//! joins zlib's: each band's block is made non-final and followed by an empty stored block
//! (which ends it on a byte boundary), a final empty block closes the stream, and the Adler-32
//! checksum of the whole is combined from the bands'. Bands are independent, so they are encoded
//! in parallel (the band writer of [`super::image::png_rows`]), and a texture streamed a band of
//! rows at a time gives the same bytes as one encoded whole.
//!
//! The join reads `fdeflate`'s output: a 2-byte zlib header, one dynamic Huffman block (final),
//! whose end-of-block code's last bit is a 1, zero padding, and the Adler-32. `Cargo.toml` pins
//! `fdeflate`'s version for that reason; the tests decode the joined streams.

/// About how many bytes of samples one band holds.
pub const BAND_BYTES: usize = 1 << 20;

/// Rows in each band of an image whose rows are `row_bytes` long (the last band may be shorter).
pub fn band_rows(row_bytes: usize) -> usize {
    BAND_BYTES.div_ceil(row_bytes.max(1)).max(1)
}

/// The zlib header of the joined stream (deflate, 32 KiB window, the fastest level's flag).
pub const ZLIB_HEADER: [u8; 2] = [0x78, 0x01];

/// One band, deflated: its blocks (ending on a byte boundary, none final), the Adler-32 of its
/// filtered bytes and how many they are.
pub struct Band {
    /// The band's deflate blocks.
    pub deflate: Vec<u8>,
    /// The Adler-32 of its filtered bytes.
    pub adler: u32,
    /// How many filtered bytes (a filter byte and the samples' bytes per row).
    pub len: u64,
}

/// Filters `rows` (whole rows of `row_bytes`, `bpp` bytes a pixel) against `above` (the row
/// before the band; zeros for the first) and deflates them into a [`Band`].
pub fn encode_band(bpp: usize, above: &[u8], rows: &[u8], row_bytes: usize) -> Band {
    let mut filtered = Vec::with_capacity(rows.len() + rows.len() / row_bytes.max(1));
    let mut scratch = Vec::with_capacity(row_bytes);
    let mut prev = above;
    for row in rows.chunks_exact(row_bytes) {
        filter_row(bpp, prev, row, &mut filtered, &mut scratch);
        prev = row;
    }
    let z = fdeflate::compress_to_vec(&filtered);
    // [0x78, 0x01] [final dynamic block ... end of block, zero padding] [Adler-32, big-endian]
    assert!(
        z.len() > 6 && z[..2] == ZLIB_HEADER && z[2] & 0b111 == 0b101,
        "fdeflate's stream is not the single final dynamic block the band join reads"
    );
    let adler = u32::from_be_bytes(z[z.len() - 4..].try_into().expect("4 bytes"));
    let mut deflate = Vec::with_capacity(z.len() + 5);
    deflate.extend_from_slice(&z[2..z.len() - 4]);
    // Not the final block.
    deflate[0] &= !1;
    // The last byte holds the end-of-block code's last bit (a 1) under the padding zeros. An
    // empty stored block (3 header bits, 0, 00; then LEN 0 and NLEN 0xffff on a byte boundary)
    // follows it: its header fits in the padding when there are 3 bits or more, else it spills
    // into one more zero byte.
    let padding = deflate.last().expect("a block").leading_zeros();
    if padding < 3 {
        deflate.push(0);
    }
    deflate.extend_from_slice(&[0, 0, 0xff, 0xff]);
    Band {
        deflate,
        adler,
        len: filtered.len() as u64,
    }
}

/// The end of the joined stream: an empty final block (fixed Huffman codes, end of block only),
/// then the Adler-32 of every filtered byte.
pub fn stream_end(adler: u32) -> [u8; 6] {
    let a = adler.to_be_bytes();
    [0x03, 0x00, a[0], a[1], a[2], a[3]]
}

/// The Adler-32 of the bytes of `a` followed by `len_b` bytes whose Adler-32 is `b` (zlib's
/// `adler32_combine`). The checksum of nothing is 1.
pub fn adler_combine(a: u32, b: u32, len_b: u64) -> u32 {
    const BASE: u64 = 65521;
    let rem = len_b % BASE;
    let (a1, a2) = (u64::from(a & 0xffff), u64::from(a >> 16));
    let (b1, b2) = (u64::from(b & 0xffff), u64::from(b >> 16));
    // b's sums start from 1: one 1 too many in the low sum, and `rem` too many in the high one.
    let lo = (a1 + b1 + BASE - 1) % BASE;
    let hi = (rem * a1 + a2 + b2 + BASE - rem) % BASE;
    (lo | (hi << 16)) as u32
}

/// Paeth's predictor of `a` (left), `b` (above) and `c` (above left), ties broken as the PNG
/// specification breaks them (a, then b).
#[inline(always)]
fn paeth(a: u8, b: u8, c: u8) -> u8 {
    let (ia, ib, ic) = (i16::from(a), i16::from(b), i16::from(c));
    let pa = (ib - ic).abs();
    let pb = (ia - ic).abs();
    let pc = (ia + ib - 2 * ic).abs();
    let ab = if pb < pa { b } else { a };
    if pc < pa.min(pb) {
        c
    } else {
        ab
    }
}

/// The adaptive heuristic's cost of a filtered row: the sum of its bytes read as signed.
fn cost(buf: &[u8]) -> u64 {
    let mut chunks = buf.chunks_exact(32);
    let mut sum = 0u64;
    for chunk in &mut chunks {
        // Summed 32 at a time in 32 bits, which the compiler vectorises.
        let part: u32 = chunk
            .iter()
            .map(|&b| u32::from((b as i8).unsigned_abs()))
            .sum();
        sum += u64::from(part);
    }
    sum + chunks
        .remainder()
        .iter()
        .map(|&b| u64::from((b as i8).unsigned_abs()))
        .sum::<u64>()
}

/// Writes `row` filtered by PNG filter `kind` (1 sub, 2 up, 3 average, 4 Paeth) into `out`.
fn apply(kind: u8, bpp: usize, prev: &[u8], row: &[u8], out: &mut [u8]) {
    let n = row.len();
    let h = bpp.min(n);
    // The first pixel has no left neighbour (a = c = 0).
    for i in 0..h {
        let (x, b) = (row[i], prev[i]);
        out[i] = match kind {
            1 => x,
            2 | 4 => x.wrapping_sub(b),
            _ => x.wrapping_sub(b >> 1),
        };
    }
    let (x, a, b, c) = (&row[h..], &row[..n - h], &prev[h..], &prev[..n - h]);
    let out = &mut out[h..];
    match kind {
        1 => {
            for (o, (x, a)) in out.iter_mut().zip(x.iter().zip(a)) {
                *o = x.wrapping_sub(*a);
            }
        }
        2 => {
            for (o, (x, b)) in out.iter_mut().zip(x.iter().zip(b)) {
                *o = x.wrapping_sub(*b);
            }
        }
        3 => {
            for (o, ((x, a), b)) in out.iter_mut().zip(x.iter().zip(a).zip(b)) {
                *o = x.wrapping_sub(((u16::from(*a) + u16::from(*b)) >> 1) as u8);
            }
        }
        _ => {
            for (o, (((x, a), b), c)) in out.iter_mut().zip(x.iter().zip(a).zip(b).zip(c)) {
                *o = x.wrapping_sub(paeth(*a, *b, *c));
            }
        }
    }
}

/// Appends `row`'s filter byte and its filtered bytes to `out`: of up, sub, average and Paeth
/// (tried in that order), the last with the smallest [`cost`]; a row that costs nothing stops
/// the search.
fn filter_row(bpp: usize, prev: &[u8], row: &[u8], out: &mut Vec<u8>, scratch: &mut Vec<u8>) {
    scratch.resize(row.len(), 0);
    let mut best = (u64::MAX, 2u8);
    for kind in [2u8, 1, 3, 4] {
        apply(kind, bpp, prev, row, scratch);
        let c = cost(scratch);
        if c <= best.0 {
            best = (c, kind);
            if c == 0 {
                break;
            }
        }
    }
    out.push(best.1);
    let start = out.len();
    out.resize(start + row.len(), 0);
    apply(best.1, bpp, prev, row, &mut out[start..]);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Adler-32 the plain way.
    fn adler(bytes: &[u8]) -> u32 {
        let (mut a, mut b) = (1u32, 0u32);
        for &x in bytes {
            a = (a + u32::from(x)) % 65521;
            b = (b + a) % 65521;
        }
        a | (b << 16)
    }

    #[test]
    fn adler_combines_as_the_whole() {
        let data: Vec<u8> = (0..200_000u32).map(|i| (i * 7919 % 251) as u8).collect();
        for cut in [0, 1, 5552, 65521, 100_000, 200_000] {
            let (x, y) = data.split_at(cut);
            assert_eq!(
                adler_combine(adler(x), adler(y), y.len() as u64),
                adler(&data),
                "cut at {cut}"
            );
        }
    }

    /// The unfiltered bytes of a joined stream, inflated by `fdeflate`'s decompressor (which
    /// checks the Adler-32).
    fn inflate(stream: &[u8]) -> Vec<u8> {
        let mut d = fdeflate::Decompressor::new();
        let mut out = vec![0u8; 1 << 24];
        let (consumed, produced) = d
            .read(stream, &mut out, 0, true)
            .expect("a valid zlib stream");
        assert!(d.is_done(), "the stream ends");
        assert_eq!(consumed, stream.len(), "nothing after the stream");
        out.truncate(produced);
        out
    }

    /// Rows of varied content: flat, gradients, noise, so that every filter and padding length
    /// comes up across the bands.
    fn rows(width: usize, height: usize, bpp: usize) -> Vec<u8> {
        let mut s = 12345u32;
        (0..width * height * bpp)
            .map(|i| {
                s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                let (x, y) = ((i / bpp) % width, i / bpp / width);
                match y % 4 {
                    0 => 200,
                    1 => (x * 3 + y) as u8,
                    2 => (s >> 24) as u8,
                    _ => ((x ^ y) & 0xf0) as u8,
                }
            })
            .collect()
    }

    #[test]
    fn joined_bands_inflate_to_the_filtered_rows() {
        for (width, height, bpp, band) in [(37, 41, 4, 5), (64, 64, 8, 7), (3, 9, 4, 1)] {
            let data = rows(width, height, bpp);
            let row_bytes = width * bpp;
            let mut stream = ZLIB_HEADER.to_vec();
            let mut adler = 1;
            let mut filtered = Vec::new();
            for (i, chunk) in data.chunks(band * row_bytes).enumerate() {
                let above = if i == 0 {
                    vec![0; row_bytes]
                } else {
                    data[i * band * row_bytes - row_bytes..i * band * row_bytes].to_vec()
                };
                let b = encode_band(bpp, &above, chunk, row_bytes);
                stream.extend_from_slice(&b.deflate);
                adler = adler_combine(adler, b.adler, b.len);
                let mut scratch = Vec::new();
                let mut prev = &above[..];
                for row in chunk.chunks_exact(row_bytes) {
                    filter_row(bpp, prev, row, &mut filtered, &mut scratch);
                    prev = row;
                }
            }
            stream.extend_from_slice(&stream_end(adler));
            assert_eq!(
                inflate(&stream),
                filtered,
                "{width}x{height}, {bpp} bytes a pixel"
            );
        }
    }

    #[test]
    fn filters_invert() {
        // Undo each filter by the PNG specification's reconstruction and compare.
        let (width, bpp) = (29, 4);
        let data = rows(width, 8, bpp);
        let row_bytes = width * bpp;
        let mut prev = vec![0u8; row_bytes];
        for row in data.chunks_exact(row_bytes) {
            for kind in 1..=4u8 {
                let mut f = vec![0; row_bytes];
                apply(kind, bpp, &prev, row, &mut f);
                let mut r = vec![0u8; row_bytes];
                for i in 0..row_bytes {
                    let a = if i >= bpp { r[i - bpp] } else { 0 };
                    let c = if i >= bpp { prev[i - bpp] } else { 0 };
                    let b = prev[i];
                    let p = match kind {
                        1 => a,
                        2 => b,
                        3 => ((u16::from(a) + u16::from(b)) / 2) as u8,
                        _ => {
                            let p = i16::from(a) + i16::from(b) - i16::from(c);
                            let (pa, pb, pc) = (
                                (p - i16::from(a)).abs(),
                                (p - i16::from(b)).abs(),
                                (p - i16::from(c)).abs(),
                            );
                            if pa <= pb && pa <= pc {
                                a
                            } else if pb <= pc {
                                b
                            } else {
                                c
                            }
                        }
                    };
                    r[i] = f[i].wrapping_add(p);
                }
                assert_eq!(r, row, "filter {kind}");
            }
            prev = row.to_vec();
        }
    }
}
