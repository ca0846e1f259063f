mod filt;
use std::time::Instant;
fn paeth(a: u8, b: u8, c: u8) -> u8 {
    let p = a as i16 + b as i16 - c as i16;
    let (pa, pb, pc) = ((p - a as i16).abs(), (p - b as i16).abs(), (p - c as i16).abs());
    if pa <= pb && pa <= pc { a } else if pb <= pc { b } else { c }
}
fn filter_row(prev: &[u8], row: &[u8], out: &mut Vec<u8>, scratch: &mut [Vec<u8>; 5]) {
    let bpp = 4;
    let n = row.len();
    for s in scratch.iter_mut() { s.clear(); s.resize(n, 0); }
    for i in 0..n {
        let a = if i >= bpp { row[i - bpp] } else { 0 };
        let b = prev[i];
        let c = if i >= bpp { prev[i - bpp] } else { 0 };
        let x = row[i];
        scratch[0][i] = x;
        scratch[1][i] = x.wrapping_sub(a);
        scratch[2][i] = x.wrapping_sub(b);
        scratch[3][i] = x.wrapping_sub(((a as u16 + b as u16) / 2) as u8);
        scratch[4][i] = x.wrapping_sub(paeth(a, b, c));
    }
    let mut best = 0; let mut bs = u64::MAX;
    for (k, s) in scratch.iter().enumerate() {
        let sum: u64 = s.iter().map(|&v| (v as i8).unsigned_abs() as u64).sum();
        if sum < bs { bs = sum; best = k; }
    }
    out.push(best as u8);
    out.extend_from_slice(&scratch[best]);
}
fn filtered_band(data: &[u8], stride: usize, y0: usize, y1: usize) -> Vec<u8> {
    let zero = vec![0u8; stride];
    let mut out = Vec::with_capacity((y1 - y0) * (stride + 1));
    let mut s: [Vec<u8>; 5] = Default::default(); let mut sc = Vec::new();
    for y in y0..y1 {
        let prev = if y == 0 { &zero[..] } else { &data[(y - 1) * stride..y * stride] };
        if std::env::var("OLD").is_ok() { filter_row(prev, &data[y * stride..(y + 1) * stride], &mut out, &mut s); } else { filt::filter_row(4, prev, &data[y * stride..(y + 1) * stride], &mut out, &mut sc); }
    }
    out
}
fn main() {
    let path = std::env::args().nth(1).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let dec = png::Decoder::new(std::io::Cursor::new(bytes));
    let mut r = dec.read_info().unwrap();
    let mut buf = vec![0; r.output_buffer_size().unwrap()];
    let info = r.next_frame(&mut buf).unwrap();
    let (w, h) = (info.width as usize, info.height as usize);
    let stride = w * 4;
    let data = &buf[..h * stride];
    let mb = data.len() as f64 / 1e6;
    for _ in 0..2 {
    // a: png crate fast adaptive
    let t = Instant::now();
    let mut out = Vec::new();
    { let mut e = png::Encoder::new(&mut out, w as u32, h as u32); e.set_color(png::ColorType::Rgba); e.set_depth(png::BitDepth::Eight);
      e.set_compression(png::Compression::Fast); e.set_filter(png::Filter::Adaptive);
      let mut wr = e.write_header().unwrap(); wr.write_image_data(data).unwrap(); }
    let ta = t.elapsed().as_secs_f64();
    println!("png-crate fast: {} bytes {:.1} ms {:.0} MB/s", out.len(), ta*1e3, mb/ta);
    // copy
    let t = Instant::now(); let c = data.to_vec(); let tc = t.elapsed().as_secs_f64(); std::hint::black_box(&c);
    println!("memcpy: {:.1} ms", tc*1e3);
    let band = (1usize << 20).div_ceil(stride).max(1);
    let bands: Vec<(usize, usize)> = (0..h).step_by(band).map(|y| (y, (y + band).min(h))).collect();
    use rayon::prelude::*;
    for threads in [1usize, 2] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        // filter only
        let t = Instant::now();
        let f: Vec<Vec<u8>> = pool.install(|| bands.par_iter().map(|&(a, b)| filtered_band(data, stride, a, b)).collect());
        let tf = t.elapsed().as_secs_f64();
        // fdeflate per band
        let t = Instant::now();
        let fd: usize = pool.install(|| f.par_iter().map(|x| fdeflate::compress_to_vec(x).len()).sum());
        let tfd = t.elapsed().as_secs_f64();
        for lvl in [1u32, 2] {
        let t = Instant::now();
        let zr: usize = pool.install(|| f.par_iter().map(|x| {
            let mut c = flate2::Compress::new(flate2::Compression::new(lvl), false);
            let mut o = Vec::with_capacity(x.len() + 1024);
            c.compress_vec(x, &mut o, flate2::FlushCompress::Sync).unwrap(); o.len() }).sum());
        let tz = t.elapsed().as_secs_f64();
        println!("threads {threads}: zlib-rs l{lvl} {zr} bytes {:.1} ms", tz*1e3);
        }
        let t = Instant::now();
        let mz: usize = pool.install(|| f.par_iter().map(|x| miniz_oxide::deflate::compress_to_vec(x, 1).len()).sum());
        let tm = t.elapsed().as_secs_f64();
        println!("threads {threads}: filter {:.1} ms; fdeflate {fd} bytes {:.1} ms; miniz1 {mz} bytes {:.1} ms", tf*1e3, tfd*1e3, tm*1e3);
    }
    }
}
