#[inline(always)]
fn paeth(a: u8, b: u8, c: u8) -> u8 {
    let (ia, ib, ic) = (a as i16, b as i16, c as i16);
    let pa = (ib - ic).abs();
    let pb = (ia - ic).abs();
    let pc = (ia + ib - 2 * ic).abs();
    let ab = if pb < pa { b } else { a };
    let pab = pa.min(pb);
    if pc < pab { c } else { ab }
}
fn cost(buf: &[u8]) -> u64 {
    let mut sum = 0u64;
    let mut ch = buf.chunks_exact(32);
    for c in &mut ch {
        let mut acc = 0u32;
        for &b in c { acc += (b as i8).unsigned_abs() as u32; }
        sum += acc as u64;
    }
    for &b in ch.remainder() { sum += (b as i8).unsigned_abs() as u64; }
    sum
}
fn apply(kind: u8, bpp: usize, prev: &[u8], row: &[u8], o: &mut [u8]) {
    let n = row.len();
    let h = bpp.min(n);
    for i in 0..h {
        let (x, b) = (row[i], prev[i]);
        o[i] = match kind { 0 | 1 => x, 2 | 4 => x.wrapping_sub(b), _ => x.wrapping_sub(b >> 1) };
    }
    let (x, a, b, c) = (&row[h..], &row[..n - h], &prev[h..], &prev[..n - h]);
    let o = &mut o[h..];
    match kind {
        0 => o.copy_from_slice(x),
        1 => for (o, (x, a)) in o.iter_mut().zip(x.iter().zip(a)) { *o = x.wrapping_sub(*a) },
        2 => for (o, (x, b)) in o.iter_mut().zip(x.iter().zip(b)) { *o = x.wrapping_sub(*b) },
        3 => for (o, ((x, a), b)) in o.iter_mut().zip(x.iter().zip(a).zip(b)) { *o = x.wrapping_sub(((*a as u16 + *b as u16) >> 1) as u8) },
        _ => for (o, (((x, a), b), c)) in o.iter_mut().zip(x.iter().zip(a).zip(b).zip(c)) { *o = x.wrapping_sub(paeth(*a, *b, *c)) },
    }
}
/// Appends the filter byte and the filtered row.
pub fn filter_row(bpp: usize, prev: &[u8], row: &[u8], out: &mut Vec<u8>, scratch: &mut Vec<u8>) {
    let n = row.len();
    scratch.resize(n, 0);
    let mut best = (u64::MAX, 0u8);
    for kind in [2u8, 1, 3, 4] {
        apply(kind, bpp, prev, row, scratch);
        let c = cost(scratch);
        if c <= best.0 { best = (c, kind); if c == 0 { break; } }
    }
    out.push(best.1);
    let start = out.len();
    out.resize(start + n, 0);
    apply(best.1, bpp, prev, row, &mut out[start..]);
}
