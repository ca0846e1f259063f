// SPDX-License-Identifier: MIT OR Apache-2.0
//! Least-squares conformal maps (Levy et al. 2002), as Maillot ("Continuous Local Parameterization of
//! Polygons", section 5) uses them for stamps: the linear system, its energy, the similarity that
//! normalises a chart, and the CPU twin (f64 CG) the tests use as the oracle.
//!
//! Per triangle with vertices flattened isometrically to `q_k` (counter-clockwise about the surface
//! normal) and opposite edges `e_k = q_{k+2} - q_{k+1}` read as complex numbers, the map `z_k = u_k +
//! i v_k` is a similarity on the triangle exactly when `Σ e_k z_k = 0`. The conformal energy is
//! `Σ_T |Σ_k e_k z_k|² / (4 A_T)`: zero for every orientation-preserving similarity, scale invariant in
//! the triangle's size. Unknowns are interleaved, `u_i` at row `2i`, `v_i` at `2i + 1`; the 6×6 block
//! of a triangle is `(R1ᵀR1 + R2ᵀR2) / (4A)` with `R1 = [a_k | -b_k]`, `R2 = [b_k | a_k]` (`e_k = a_k +
//! i b_k`). Fixed vertices (two pins for a free chart; the held expmap vertices of a hybrid decal)
//! become identity rows and their columns move to the right-hand side, so the system stays SPD.

use crate::mesh::Topology;
use crate::solve::sparse::Csr;
use glam::{DVec2, DVec3};
use rustc_hash::{FxHashMap as HashMap, FxHashSet as HashSet};

/// Triangles whose area is below this fraction of their longest edge squared are skipped: they
/// carry no angle to preserve and would only add huge weights.
const SLIVER: f64 = 1e-10;

/// The opposite-edge coefficients `(a_k, b_k)` of a welded triangle and its area, or `None` for a
/// degenerate one.
pub fn triangle_edges(topo: &Topology, tri: [u32; 3]) -> Option<([DVec2; 3], f64)> {
    triangle_edges_at(tri.map(|v| topo.positions[v as usize].as_dvec3()))
}

/// [`triangle_edges`] of a triangle given by its corners.
pub fn triangle_edges_at(p: [DVec3; 3]) -> Option<([DVec2; 3], f64)> {
    let e1 = p[1] - p[0];
    let e2 = p[2] - p[0];
    let n = e1.cross(e2);
    let area = 0.5 * n.length();
    let l1 = e1.length();
    let longest = e1
        .length_squared()
        .max(e2.length_squared())
        .max((p[2] - p[1]).length_squared());
    if area.is_nan() || area <= SLIVER * longest || l1 == 0.0 {
        return None;
    }
    let x = e1 / l1;
    let y = n.cross(x).normalize();
    let q = [
        DVec2::ZERO,
        DVec2::new(l1, 0.0),
        DVec2::new(e2.dot(x), e2.dot(y)),
    ];
    Some(([q[2] - q[1], q[0] - q[2], q[1] - q[0]], area))
}

/// A chart's LSCM system over `vertices` (welded ids; unknown `i` is `vertices[i]`), from `triangles`.
#[derive(Debug, Clone)]
pub struct System {
    /// The `2n × 2n` matrix (fixed unknowns as identity rows).
    pub matrix: Csr,
    /// Right-hand side.
    pub rhs: Vec<f64>,
    /// Welded vertex of each local index.
    pub vertices: Vec<u32>,
    /// Local index of each welded vertex.
    pub local: HashMap<u32, u32>,
    /// Triangles in the energy.
    pub triangles: Vec<u32>,
    /// Fixed local vertices and their coordinates.
    pub fixed: Vec<(u32, [f64; 2])>,
}

/// Assembles the LSCM system of `triangles` with `fixed` welded vertices held at the given
/// coordinates. Vertices are numbered in order of first appearance. A vertex touched only by skipped
/// sliver triangles has no energy row; it is held at `warm(v)`.
pub fn assemble(
    topo: &Topology,
    triangles: &[u32],
    fixed: &[(u32, [f64; 2])],
    warm: &dyn Fn(u32) -> [f64; 2],
) -> System {
    let mut local: HashMap<u32, u32> = HashMap::default();
    let mut vertices = Vec::new();
    for &t in triangles {
        for v in topo.triangles[t as usize] {
            local.entry(v).or_insert_with(|| {
                vertices.push(v);
                vertices.len() as u32 - 1
            });
        }
    }
    let n = vertices.len();
    let mut value: Vec<Option<[f64; 2]>> = vec![None; n];
    let mut fixed_local = Vec::new();
    for &(v, c) in fixed {
        if let Some(&i) = local.get(&v) {
            value[i as usize] = Some(c);
            fixed_local.push((i, c));
        }
    }
    let local_tris: Vec<[u32; 3]> = triangles
        .iter()
        .map(|&t| topo.triangles[t as usize].map(|v| local[&v]))
        .collect();
    let (matrix, rhs) = assemble_local(
        &local_tris,
        &|k| triangle_edges(topo, topo.triangles[triangles[k] as usize]),
        &value,
        &|i| warm(vertices[i]),
    );
    System {
        matrix,
        rhs,
        vertices,
        local,
        triangles: triangles.to_vec(),
        fixed: fixed_local,
    }
}

/// The LSCM matrix and right-hand side over `n = value.len()` vertices numbered 0..n: `triangles`
/// in those numbers, `edges(k)` the opposite-edge coefficients and area of triangle `k` (`None`
/// skips it), `value[i]` a fixed vertex's coordinates, `warm(i)` where a vertex without energy is
/// held. [`assemble`] uses it on welded vertices; `pelt::refine` on a cut piece's own vertices.
pub fn assemble_local(
    triangles: &[[u32; 3]],
    edges: &dyn Fn(usize) -> Option<([DVec2; 3], f64)>,
    value: &[Option<[f64; 2]>],
    warm: &dyn Fn(usize) -> [f64; 2],
) -> (Csr, Vec<f64>) {
    let n = value.len();
    let mut trip: Vec<(u32, u32, f64)> = Vec::with_capacity(triangles.len() * 36);
    let mut rhs = vec![0.0; 2 * n];
    for (k, tri) in triangles.iter().enumerate() {
        let Some((e, area)) = edges(k) else {
            continue;
        };
        let w = 1.0 / (4.0 * area);
        let idx = tri.map(|v| v as usize);
        // dof j in 0..6: (vertex k = j % 3, component j / 3), coefficient rows R1, R2.
        let dof = |j: usize| 2 * idx[j % 3] + j / 3;
        let r1 = |j: usize| if j < 3 { e[j].x } else { -e[j - 3].y };
        let r2 = |j: usize| if j < 3 { e[j].y } else { e[j - 3].x };
        for i in 0..6 {
            let (gi, vi) = (dof(i), value[idx[i % 3]]);
            if vi.is_some() {
                continue;
            }
            for j in 0..6 {
                let m = w * (r1(i) * r1(j) + r2(i) * r2(j));
                let gj = dof(j);
                match value[idx[j % 3]] {
                    Some(c) => rhs[gi] -= m * c[j / 3],
                    None => trip.push((gi as u32, gj as u32, m)),
                }
            }
        }
    }
    for (i, c) in value.iter().enumerate() {
        if let Some(c) = c {
            for k in 0..2 {
                trip.push(((2 * i + k) as u32, (2 * i + k) as u32, 1.0));
                rhs[2 * i + k] = c[k];
            }
        }
    }
    // A free vertex touched only by skipped slivers has an empty row: hold it where it starts.
    let mut has_row = vec![false; 2 * n];
    for &(r, _, _) in &trip {
        has_row[r as usize] = true;
    }
    for (r, h) in has_row.iter().enumerate() {
        if !h {
            trip.push((r as u32, r as u32, 1.0));
            rhs[r] = warm(r / 2)[r % 2];
        }
    }
    (Csr::from_triplets(2 * n, trip), rhs)
}

/// Conformal energy `Σ |Σ e_k z_k|² / (4A)` of per-vertex coordinates `z` (indexed by welded id
/// through `coord`) over `triangles`.
pub fn conformal_energy(
    topo: &Topology,
    triangles: &[u32],
    coord: impl Fn(u32) -> [f64; 2],
) -> f64 {
    let mut sum = 0.0;
    for &t in triangles {
        let tri = topo.triangles[t as usize];
        let Some((e, area)) = triangle_edges(topo, tri) else {
            continue;
        };
        let (mut re, mut im) = (0.0, 0.0);
        for k in 0..3 {
            let z = coord(tri[k]);
            re += e[k].x * z[0] - e[k].y * z[1];
            im += e[k].y * z[0] + e[k].x * z[1];
        }
        sum += (re * re + im * im) / (4.0 * area);
    }
    sum
}

/// Signed area of the chart's image and the surface area of `triangles`.
pub fn areas(topo: &Topology, triangles: &[u32], coord: impl Fn(u32) -> [f64; 2]) -> (f64, f64) {
    let (mut img, mut surf) = (0.0, 0.0);
    for &t in triangles {
        let tri = topo.triangles[t as usize];
        let p = tri.map(|v| topo.positions[v as usize].as_dvec3());
        surf += 0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length();
        let z = tri.map(|v| DVec2::from(coord(v)));
        img += 0.5 * (z[1] - z[0]).perp_dot(z[2] - z[0]);
    }
    (img, surf)
}

/// The similarity `z -> alpha z + beta` (complex `alpha = (re, im)`) that normalises a chart
/// (Maillot section 7's alignment, fixed at the placed point): the seed point lands on 0, the frame's
/// axes map onto +x and +y (least squares of the Jacobian's images of the axes over the triangles
/// around the seed triangle), and the chart's scale at the seed point is 1 ([`scale_at`] over the
/// vertices within `fit_radius`). A global fit (matching the chart's area to the surface's) would be
/// dominated by the chart's far parts, where the conformal factor of a curved region differs most.
#[allow(clippy::too_many_arguments, reason = "the frame")]
pub fn normalising_similarity(
    topo: &Topology,
    triangles: &[u32],
    coord: &dyn Fn(u32) -> [f64; 2],
    seed_triangle: u32,
    seed_point: DVec3,
    axis_u: DVec3,
    axis_v: DVec3,
    fit_radius: f64,
) -> Option<(DVec2, DVec2)> {
    let st = topo.triangles[seed_triangle as usize];
    let around = seed_ring(topo, triangles, seed_triangle);
    let (mut ju, mut jv) = (DVec2::ZERO, DVec2::ZERO);
    for &t in &around {
        let tri = topo.triangles[t as usize];
        let p = tri.map(|v| topo.positions[v as usize].as_dvec3());
        let z = tri.map(|v| DVec2::from(coord(v)));
        let (d1, d2) = (p[1] - p[0], p[2] - p[0]);
        let n = d1.cross(d2);
        let area = 0.5 * n.length();
        if area <= 0.0 {
            continue;
        }
        // Gradient of the map along a 3D tangent vector t: solve [d1 d2] c = t (in the plane).
        let g = |t: DVec3| -> DVec2 {
            let t = t - t.dot(n) / n.length_squared() * n;
            let (a11, a12, a22) = (d1.dot(d1), d1.dot(d2), d2.dot(d2));
            let det = a11 * a22 - a12 * a12;
            let (r1, r2) = (d1.dot(t), d2.dot(t));
            let c1 = (a22 * r1 - a12 * r2) / det;
            let c2 = (a11 * r2 - a12 * r1) / det;
            c1 * (z[1] - z[0]) + c2 * (z[2] - z[0])
        };
        ju += area * g(axis_u);
        jv += area * g(axis_v);
    }
    if !(ju.length() > 0.0 && jv.length() > 0.0) {
        return None;
    }
    // Rotation r (unit complex) with r ju ≈ +x and r jv ≈ +y: r = conj(ju^) + i conj(jv^) normalised.
    let cu = ju.normalize();
    let cv = jv.normalize();
    let rot = DVec2::new(cu.x + cv.y, -cu.y + cv.x);
    let rot = if rot.length() > 0.0 {
        rot.normalize()
    } else {
        DVec2::X
    };
    // Seed point's image.
    let p = st.map(|v| topo.positions[v as usize].as_dvec3());
    let bary = barycentric(p, seed_point);
    let zs = st
        .iter()
        .zip(bary)
        .fold(DVec2::ZERO, |acc, (&v, w)| acc + w * DVec2::from(coord(v)));
    let scale = scale_at(
        topo,
        triangles,
        coord,
        seed_triangle,
        seed_point,
        zs,
        fit_radius,
    )?;
    let alpha = rot / scale;
    let beta = -cmul(alpha, zs);
    Some((alpha, beta))
}

/// The triangles of `triangles` that share a vertex with the seed triangle (its one-ring).
fn seed_ring(topo: &Topology, triangles: &[u32], seed_triangle: u32) -> Vec<u32> {
    let mut around: Vec<u32> = Vec::new();
    for v in topo.triangles[seed_triangle as usize] {
        around.extend(topo.triangles_around(v));
    }
    let in_chart: HashSet<u32> = triangles.iter().copied().collect();
    around.retain(|t| in_chart.contains(t));
    around.sort_unstable();
    around.dedup();
    around
}

/// The chart's scale at the seed point `p` (image `zs`): the median, over the chart's vertices
/// within `radius` of `p` (3D distance; at least the vertices of the seed triangle's one-ring), of
/// |z_v − zs| / |x_v − p|. For a conformal map this tends to the Jacobian's scale at `p` as the
/// radius shrinks. It is stable where a single triangle's Jacobian is not: a median over a ring of
/// vertices ignores one sliver triangle, and at the tip of a horn or a cone (where the per-triangle
/// Jacobians of a conformal flattening vary most) it measures what a viewer reads as the decal's
/// size, the distance from its centre. `None` when no vertex is usable.
pub fn scale_at(
    topo: &Topology,
    triangles: &[u32],
    coord: &dyn Fn(u32) -> [f64; 2],
    seed_triangle: u32,
    p: DVec3,
    zs: DVec2,
    radius: f64,
) -> Option<f64> {
    let ring: HashSet<u32> = seed_ring(topo, triangles, seed_triangle)
        .iter()
        .flat_map(|&t| topo.triangles[t as usize])
        .collect();
    let mut vertices: Vec<u32> = triangles
        .iter()
        .flat_map(|&t| topo.triangles[t as usize])
        .collect();
    vertices.sort_unstable();
    vertices.dedup();
    let mut ratios: Vec<f64> = vertices
        .iter()
        .filter_map(|&v| {
            let d = (topo.positions[v as usize].as_dvec3() - p).length();
            let near = d <= radius || ring.contains(&v);
            let r = (DVec2::from(coord(v)) - zs).length() / d;
            (near && d > 1e-9 * radius.max(f64::MIN_POSITIVE) && r.is_finite() && r > 0.0)
                .then_some(r)
        })
        .collect();
    ratios.sort_by(f64::total_cmp);
    ratios.get(ratios.len() / 2).copied()
}

/// Complex product.
pub fn cmul(a: DVec2, b: DVec2) -> DVec2 {
    DVec2::new(a.x * b.x - a.y * b.y, a.x * b.y + a.y * b.x)
}

/// Barycentric coordinates of `q` (projected) in triangle `p`.
pub fn barycentric(p: [DVec3; 3], q: DVec3) -> [f64; 3] {
    let (e1, e2, d) = (p[1] - p[0], p[2] - p[0], q - p[0]);
    let (a11, a12, a22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let (r1, r2) = (e1.dot(d), e2.dot(d));
    let det = a11 * a22 - a12 * a12;
    if det.abs() < f64::MIN_POSITIVE {
        return [1.0 / 3.0; 3];
    }
    let b1 = (a22 * r1 - a12 * r2) / det;
    let b2 = (a11 * r2 - a12 * r1) / det;
    [1.0 - b1 - b2, b1, b2]
}

/// CPU twin: solves `sys` in f64 (Jacobi PCG to a relative residual of 1e-12) from `x0`.
pub fn solve_cpu(sys: &System, x0: &[f64]) -> (Vec<f64>, crate::solve::sparse::CgReport) {
    let mut x = x0.to_vec();
    let rep = crate::solve::cg::pcg(&sys.matrix, &sys.rhs, &mut x, 1e-12, 100_000);
    (x, rep)
}

/// Cotangent Laplacian plus `shift` times the lumped mass of `topo` (SPD for `shift > 0`): a real
/// mesh system for the solver tests and benchmarks.
pub fn shifted_laplacian(topo: &Topology, shift: f64) -> Csr {
    let n = topo.positions.len();
    let mut trip = Vec::new();
    for (t, tri) in topo.triangles.iter().enumerate() {
        if topo.degenerate[t] {
            continue;
        }
        let p = tri.map(|v| topo.positions[v as usize].as_dvec3());
        let area = 0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length();
        if area <= 0.0 {
            continue;
        }
        for k in 0..3 {
            let (i, j, o) = (tri[(k + 1) % 3], tri[(k + 2) % 3], p[k]);
            let (a, b) = (p[(k + 1) % 3] - o, p[(k + 2) % 3] - o);
            // Clamp cotangents of nearly flat angles so the matrix stays an M-matrix-like SPD system.
            let cot = (a.dot(b) / a.cross(b).length()).clamp(-10.0, 10.0);
            let w = 0.5 * cot.max(0.0) + 1e-3;
            trip.push((i, j, -w));
            trip.push((j, i, -w));
            trip.push((i, i, w));
            trip.push((j, j, w));
            trip.push((tri[k], tri[k], shift * area / 3.0));
        }
    }
    for v in 0..n as u32 {
        trip.push((v, v, 0.0));
    }
    Csr::from_triplets(n, trip)
}
