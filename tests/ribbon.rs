// SPDX-License-Identifier: MIT OR Apache-2.0
//! The extended exponential map of a curve (`decalbake::maps::ribbon`, Sun et al. 2013 §3), CPU
//! twin, against analytic Fermi coordinates: on a plane around a circular arc (exact up to the
//! polyline's chords), on a cylinder along a helix (the unrolled coordinates; converging under
//! refinement).

mod common;

use decalbake::maps::ribbon::gpu::ribbon_gpu;
use decalbake::maps::ribbon::{ribbon_cpu, Curve, RibbonMap};
use decalbake::mesh::{Mesh, Topology, DEFAULT_WELD_TOLERANCE};
use decalbake::place::{place_cpu, Query};
use glam::{Vec2, Vec3};
use std::f32::consts::PI;

/// A flat square grid in z = 0, `n` × `n` cells over [−1, 1]², normal +z.
fn plane(n: u32) -> Mesh {
    let mut positions = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let f = |k: u32| -1.0 + 2.0 * k as f32 / n as f32;
            positions.push(Vec3::new(f(i), f(j), 0.0));
        }
    }
    let mut triangles = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let a = j * (n + 1) + i;
            let (b, c, d) = (a + 1, a + n + 1, a + n + 2);
            triangles.push([a, b, d]);
            triangles.push([a, d, c]);
        }
    }
    let k = positions.len();
    Mesh {
        source: "plane".into(),
        positions,
        normals: vec![Vec3::Z; k],
        uv_sets: vec![vec![Vec2::ZERO; k]],
        triangles,
        primitives: vec![],
        material: None,
        blend: Vec::new(),
        bridge: Vec::new(),
        ..Default::default()
    }
}

/// The curve through `points` (on the surface), each piece in the triangle of its midpoint.
fn curve(topo: &Topology, points: Vec<Vec3>) -> Curve {
    let triangles = points
        .windows(2)
        .map(|w| place_cpu(topo, Query::Point((w[0] + w[1]) * 0.5)).triangle)
        .collect();
    Curve { points, triangles }
}

/// Largest |uv − exact| over reached vertices for which `exact` gives a value.
fn max_error(
    topo: &Topology,
    map: &RibbonMap,
    exact: impl Fn(Vec3) -> Option<[f32; 2]>,
) -> (f32, usize) {
    let (mut worst, mut n) = (0.0f32, 0);
    for v in 0..topo.positions.len() {
        let Some(e) = exact(topo.positions[v]).filter(|_| map.reached(v)) else {
            continue;
        };
        let c = map.uv[v];
        worst = worst.max((c[0] - e[0]).hypot(c[1] - e[1]));
        n += 1;
    }
    (worst, n)
}

/// On a plane, around a circular arc of radius R = 0.6 (centre at the origin, from θ = −π/3 to
/// π/3, counter-clockwise, sampled every 0.01): a point at radius ρ and angle θ inside the arc's
/// span has Fermi coordinates u = R (θ + π/3), v = R − ρ (N × T points to the centre). Within
/// |v| < 0.25 the map matches them to 2e-4 (measured 1.6e-5): the polyline's chords are 0.01
/// long, so it lies up to 2e-5 inside the circle and is 2e-5 shorter over its length. Read
/// against the polyline itself instead of the arcs its pieces stand for, the same check fails
/// (3.3e-3: beside each knot u is off by |v| times half the turning angle).
#[test]
fn plane_arc_gets_fermi_coordinates() {
    let mesh = plane(80);
    let topo = Topology::build(&mesh, DEFAULT_WELD_TOLERANCE);
    let r = 0.6;
    let (t0, t1) = (-PI / 3.0, PI / 3.0);
    let steps = ((t1 - t0) * r / 0.01).ceil() as usize;
    let points = (0..=steps)
        .map(|k| {
            let t = t0 + (t1 - t0) * k as f32 / steps as f32;
            Vec3::new(r * t.cos(), r * t.sin(), 0.0)
        })
        .collect();
    let c = curve(&topo, points);
    let map = ribbon_cpu(&topo, &c, 0.3);
    assert!(
        (map.length - r * (t1 - t0)).abs() < 1e-3,
        "length {}",
        map.length
    );
    let exact = |p: Vec3| {
        let (rho, t) = (p.truncate().length(), p.y.atan2(p.x));
        // Inside the span, away from its ends by a little (the ends' feet are the end points).
        (t > t0 + 0.02 && t < t1 - 0.02 && (r - rho).abs() < 0.25)
            .then_some([r * (t - t0), r - rho])
    };
    let (err, n) = max_error(&topo, &map, exact);
    eprintln!("plane arc: {n} vertices, max error {err:.2e}");
    assert!(n > 500, "{n} vertices checked");
    assert!(err < 2e-4, "max error {err:.2e}");
    // Beyond the end, the tangential offset continues u: a point straight ahead of the end along
    // its tangent is at u = length + distance.
    let end = Vec3::new(r * t1.cos(), r * t1.sin(), 0.0);
    let ahead = end + Vec3::new(-t1.sin(), t1.cos(), 0.0) * 0.1;
    let v = (0..topo.positions.len())
        .filter(|&v| map.reached(v))
        .min_by(|&a, &b| {
            let d = |v: usize| (topo.positions[v] - ahead).length();
            d(a).total_cmp(&d(b))
        })
        .unwrap();
    let p = topo.positions[v];
    let local = p - end;
    let t = Vec3::new(-t1.sin(), t1.cos(), 0.0);
    let want = [map.length + local.dot(t), Vec3::Z.cross(t).dot(local)];
    let got = map.uv[v];
    assert!(
        (got[0] - want[0]).abs() < 1e-3 && (got[1] - want[1]).abs() < 1e-3,
        "past the end: {got:?} vs {want:?}"
    );
}

/// A circular arc on the flat grid (centre at the origin, counter-clockwise from `t0` to `t1`) given
/// by `points` evenly spaced path points, and its Fermi coordinates: at radius ρ and angle θ
/// inside the span, u = r (θ − t0) along it and v = r − ρ across it (N × T points to the centre:
/// v > 0 inside the turn).
#[derive(Clone, Copy)]
struct Circle {
    r: f32,
    t0: f32,
    t1: f32,
    points: usize,
}

impl Circle {
    fn path(&self) -> Vec<Vec3> {
        (0..self.points)
            .map(|k| {
                let t = self.t0 + (self.t1 - self.t0) * k as f32 / (self.points - 1) as f32;
                Vec3::new(self.r * t.cos(), self.r * t.sin(), 0.0)
            })
            .collect()
    }

    /// (u, v) of `p` where it lies beside the arc within `half` of it.
    fn fermi(&self, p: Vec3, half: f32) -> Option<[f32; 2]> {
        let (rho, t) = (p.truncate().length(), p.y.atan2(p.x));
        let (u, v) = (self.r * (t - self.t0), self.r - rho);
        (t >= self.t0 && t <= self.t1 && v.abs() <= half).then_some([u, v])
    }

    /// The turning angle at each point of the polyline through the path points.
    fn corner(&self) -> f32 {
        (self.t1 - self.t0) / (self.points - 1) as f32
    }
}

/// A quarter circle of radius 0.5 through 13 points (7.5° apart) and a half circle of radius 0.3
/// through 37 (5° apart).
const CIRCLES: [Circle; 2] = [
    Circle {
        r: 0.5,
        t0: 0.0,
        t1: PI / 2.0,
        points: 13,
    },
    Circle {
        r: 0.3,
        t0: 0.0,
        t1: PI,
        points: 37,
    },
];

/// The path through `points` on the flat grid as a ribbon layer's path is laid there: the chord
/// from each point to the next (the plane's geodesic) sampled every quarter of the mean edge,
/// each piece in the triangle of its end (as `stroke::path::walk` samples the geodesic join),
/// then, unless `linear`, the points' Catmull-Rom spline laid along it (`spline::smooth`).
fn plane_path(topo: &Topology, points: &[Vec3], linear: bool) -> Curve {
    use decalbake::bake::kinds::stroke::{path, spline};
    let step = 0.25 * path::mean_edge(topo);
    let on = |p: Vec3| place_cpu(topo, Query::Point(p)).triangle;
    let mut joined = path::SurfacePath {
        points: vec![points[0]],
        triangles: Vec::new(),
        arc: vec![0.0],
        knots: vec![0.0],
    };
    for w in points.windows(2) {
        let n = ((w[1] - w[0]).length() / step).ceil() as usize;
        for j in 1..=n {
            let p = w[0].lerp(w[1], j as f32 / n as f32);
            let s = joined.length() + (p - *joined.points.last().unwrap()).length();
            joined.points.push(p);
            joined.triangles.push(on(p));
            joined.arc.push(s);
        }
        joined.knots.push(joined.length());
    }
    let laid = if linear {
        joined
    } else {
        spline::smooth(topo, &joined, points, step)
    };
    Curve {
        points: laid.points,
        triangles: laid.triangles,
    }
}

/// Largest |u − exact u| and |v − exact v| over the vertices `map` gives (u, v) for that lie beside
/// `circle` within `half`, on its outside and on its inside (v > 0), and how many there are.
fn errors_by_side(
    topo: &Topology,
    circle: &Circle,
    half: f32,
    map: impl Fn(usize) -> Option<[f32; 2]>,
) -> [([f32; 2], usize); 2] {
    let mut out = [([0.0f32; 2], 0usize); 2];
    for v in 0..topo.positions.len() {
        let Some(e) = circle.fermi(topo.positions[v], half) else {
            continue;
        };
        let Some(c) = map(v) else {
            panic!("vertex {v} beside the curve not reached");
        };
        let side = &mut out[(e[1] > 0.0) as usize];
        side.0[0] = side.0[0].max((c[0] - e[0]).abs());
        side.0[1] = side.0[1].max((c[1] - e[1]).abs());
        side.1 += 1;
    }
    out
}

/// The bounds [`circle_paths_get_fermi_coordinates_on_both_sides`] holds a ribbon's map along
/// `circle` to, in u and in v, within `half` of a curve of length `length`: 1e-4 × r along the
/// points' spline; along their polyline (`linear`), whose chords lie up to a sagitta inside the
/// circle and whose corners turn by α, the sagitta in v and (`half`) α plus the polyline's
/// shortfall in length in u (beside a corner the nearest point jumps across it on the inside and
/// stays on it on the outside), with 2e-4 to spare.
fn circle_bounds(circle: &Circle, linear: bool, half: f32, length: f32) -> [f32; 2] {
    if !linear {
        return [1e-4 * circle.r; 2];
    }
    let a = circle.corner();
    let short = circle.r * (circle.t1 - circle.t0) - length;
    let sagitta = circle.r * (1.0 - (0.5 * a).cos());
    [half * a + short + 2e-4, sagitta + 2e-4]
}

/// Checks a ribbon map's errors by side ([`errors_by_side`]) against [`circle_bounds`]; `what`
/// names the case in messages.
fn check_circle(sides: [([f32; 2], usize); 2], bounds: [f32; 2], what: &str) {
    eprintln!(
        "{what}: outside {:.1e} {:.1e} ({} vertices), inside {:.1e} {:.1e} ({}); bounds {:.1e} {:.1e}",
        sides[0].0[0], sides[0].0[1], sides[0].1, sides[1].0[0], sides[1].0[1], sides[1].1,
        bounds[0], bounds[1]
    );
    for (e, n) in sides {
        assert!(n > 20, "{what}: {n} vertices checked");
        assert!(
            e[0] < bounds[0] && e[1] < bounds[1],
            "{what}: error {e:?} over {bounds:?}"
        );
    }
}

/// A ribbon 0.2 wide along path points on a circle ([`CIRCLES`]) on the flat grid at three
/// densities (40, 64 and 100 cells a side), its map by the CPU twin: at every vertex of the strip,
/// on both sides of the curve, u and v are the circle's Fermi coordinates within 1e-4 × its radius
/// (measured up to 4.8e-5 × r in u, 7e-6 × r in v). The curve is the points' Catmull-Rom spline,
/// sampled so densely that its chords lie within 8e-6 × r of it. The spline through points 7.5°
/// apart is within 7e-6 × r of the circle, but its tangent wavers, so the nearest points of
/// vertices 0.1 away shift along it: 4.8e-5 × r for the quarter circle, and 1.05e-4 × r for a half
/// circle of radius 0.3 through 25 points, hence 37 (through 17 points 3.1e-4 × r; through 9,
/// 22.5° apart, 3e-3 × r in u and 5.5e-4 × r in v: the interpolation's error falls as the cube
/// of the spacing).
///
/// Through the same points with `"interpolate": "linear"` the curve is the polyline, and the map
/// holds its bounds ([`circle_bounds`]: measured 7.8e-3 and 5.4e-3 in u against 1.4e-2 and 9.2e-3).
/// The map used to read each piece as an arc with its knots' turning over its own length: the
/// pieces beside each corner (a quarter of an edge long, where the geodesics between the points
/// meet) were arcs of radius 0.04 to 0.09, and vertices inside the turn beyond that had their
/// radial foot on the far side of the arc: along the quarter circle's polyline on the finest grid,
/// u off by up to 0.25 and v by 0.034 (the reported detached spots inside the curve; the half
/// circle's, 1.3e-2 in u). [`plane_arc_gets_fermi_coordinates`] did not show it: its 121 points
/// are 0.0105 apart, each chord one piece, so every piece was read with the circle's own
/// curvature; and no path was smooth, so the spline's bounds failed on every grid (3.3e-3 to
/// 0.25 in u, the sagitta, 1.1e-3 and 2.9e-4, in v).
#[test]
fn circle_paths_get_fermi_coordinates_on_both_sides() {
    let half = 0.1f32;
    for cells in [40, 64, 100] {
        let topo = Topology::build(&plane(cells), DEFAULT_WELD_TOLERANCE);
        let reach = 1.2 * half + 2.0 * 2.0 / cells as f32;
        for circle in CIRCLES {
            for linear in [false, true] {
                let c = plane_path(&topo, &circle.path(), linear);
                let map = ribbon_cpu(&topo, &c, reach);
                let sides =
                    errors_by_side(&topo, &circle, half, |v| map.reached(v).then(|| map.uv[v]));
                let what = format!("r {}, {cells} cells, linear {linear}", circle.r);
                check_circle(
                    sides,
                    circle_bounds(&circle, linear, half, map.length),
                    &what,
                );
            }
        }
    }
}

/// The ribbons of [`circle_paths_get_fermi_coordinates_on_both_sides`] as a bake lays them
/// (`Engine::units`: the path points placed, joined by geodesics on the GPU, along the spline
/// unless `"interpolate": "linear"`), mapped by the GPU relaxation and by its CPU twin on the same
/// curve: both within the same bounds (measured as there).
#[test]
fn baked_circle_ribbons_get_fermi_coordinates_on_both_sides() {
    let engine = common::engine();
    let dir = common::scratch("ribbon_circles");
    flat_scene(&dir);
    let half = 0.1f32;
    for cells in [40, 64, 100] {
        let loaded = engine.prepare(plane(cells)).unwrap();
        let topo = &loaded.topo;
        for circle in CIRCLES {
            for linear in [false, true] {
                let path: Vec<[f32; 3]> = circle.path().iter().map(|p| p.to_array()).collect();
                let mut layer = serde_json::json!({ "kind": "ribbon", "image": "grad.png",
                    "path": path, "width": 2.0 * half });
                if linear {
                    layer["interpolate"] = "linear".into();
                }
                let text =
                    serde_json::json!({ "mesh": "plane.glb", "layers": [layer] }).to_string();
                let job = decalbake::Job::parse(&text, &dir.join("job.json"), &dir, &dir).unwrap();
                let units = engine.units(&loaded, &job).unwrap();
                let r = units
                    .ribbons
                    .iter()
                    .flatten()
                    .next()
                    .expect("a ribbon unit");
                let twin = ribbon_cpu(topo, &r.curve, r.reach);
                let bounds = circle_bounds(&circle, linear, half, twin.length);
                let what = format!("r {}, {cells} cells, linear {linear}", circle.r);
                let sides =
                    errors_by_side(topo, &circle, half, |v| twin.reached(v).then(|| twin.uv[v]));
                check_circle(sides, bounds, &format!("{what}, twin"));
                let (gpu, status) = ribbon_gpu(
                    &engine.ctx,
                    engine.pipelines(),
                    loaded.surface_ref(),
                    &r.curve,
                    r.reach,
                )
                .unwrap();
                assert!(status.converged, "{what}: {status:?}");
                let sides = errors_by_side(topo, &circle, half, |v| {
                    (gpu[v][3] > 0.5).then(|| [gpu[v][0], gpu[v][1]])
                });
                check_circle(sides, bounds, &format!("{what}, GPU"));
            }
        }
    }
}

/// On the cylinder of radius 1 (axis z), a helix θ = θ0 + s cos α, z = s sin α unrolls to a
/// straight line in (θ, z): its Fermi coordinates are u = the unrolled point's position along the
/// line and v = its offset across it (towards +θ after a quarter turn right of the line's
/// direction, N × T with N outward). The map matches them within |v| < 0.3 and away from the ends,
/// and the error shrinks under refinement (32 × 16 → 64 × 32 → 128 × 64 cells; measured 3.2e-3,
/// 1.3e-3, 4.7e-4): the cylinder is developable, so only the mesh's chords and the propagation's
/// graph paths cause error. Without the foot's sliding (each vertex keeping the foot where its
/// Dijkstra path started) the finest error is 1.9e-3, above the 1e-3 bound.
#[test]
fn cylinder_helix_gets_the_unrolled_coordinates() {
    let alpha: f32 = 0.4;
    let mut errors = Vec::new();
    for (n, m) in [(32u32, 16u32), (64, 32), (128, 64)] {
        let mesh = common::cylinder(n, m);
        let topo = Topology::build(&mesh, DEFAULT_WELD_TOLERANCE);
        let len = 1.6;
        let steps = (len / 0.005) as usize;
        let (th0, z0) = (-0.6f32, -0.3f32);
        let dir = Vec2::new(alpha.cos(), alpha.sin());
        let on = |s: f32| {
            let (th, z) = (th0 + s * dir.x, z0 + s * dir.y);
            // Onto the faceted surface: the nearest point of the mesh.
            let q = place_cpu(&topo, Query::Point(Vec3::new(th.cos(), th.sin(), z)));
            Vec3::from(q.point)
        };
        let points = (0..=steps)
            .map(|k| on(len * k as f32 / steps as f32))
            .collect();
        let c = curve(&topo, points);
        let map = ribbon_cpu(&topo, &c, 0.35);
        let exact = |p: Vec3| {
            let w = Vec2::new(p.y.atan2(p.x) - th0, p.z - z0);
            let (u, v) = (w.dot(dir), dir.perp().dot(w));
            (u > 0.05 && u < len - 0.05 && v.abs() < 0.3).then_some([u, v])
        };
        let (err, k) = max_error(&topo, &map, exact);
        eprintln!(
            "cylinder {n}x{m}: {k} vertices, max error {err:.2e} (length {})",
            map.length
        );
        assert!(k > 20, "{k} vertices checked");
        errors.push(err);
    }
    for w in errors.windows(2) {
        assert!(
            w[1] < 0.7 * w[0],
            "refinement must shrink the error: {errors:?}"
        );
    }
    assert!(errors[2] < 1e-3, "{errors:?}");
}

/// Largest |GPU − CPU twin| over (u, v) and the graph distance, after checking that both reached
/// the same vertices and that the GPU relaxation converged.
fn gpu_against_twin(
    engine: &decalbake::Engine,
    mesh: Mesh,
    curve_of: impl Fn(&Topology) -> Curve,
    reach: f32,
) -> (f32, usize) {
    let loaded = engine.prepare(mesh).unwrap();
    let topo = &loaded.topo;
    let c = curve_of(topo);
    // A surface curve: consecutive points close together (no jump across the model).
    let longest = c
        .points
        .windows(2)
        .map(|w| (w[1] - w[0]).length())
        .fold(0.0f32, f32::max);
    assert!(longest < 0.02, "a piece of {longest}");
    let twin = ribbon_cpu(topo, &c, reach);
    let (gpu, status) = ribbon_gpu(
        &engine.ctx,
        engine.pipelines(),
        loaded.surface_ref(),
        &c,
        reach,
    )
    .unwrap();
    assert!(status.converged, "{status:?}");
    let (mut gap, mut n) = (0.0f32, 0);
    for (v, g) in gpu.iter().enumerate() {
        assert_eq!(
            g[3] > 0.5,
            twin.reached(v),
            "vertex {v} reached on one side only"
        );
        if g[3] > 0.5 {
            let t = twin.uv[v];
            let d = (g[0] - t[0])
                .abs()
                .max((g[1] - t[1]).abs())
                .max((g[2] - twin.dist[v]).abs());
            gap = if d.is_nan() {
                f32::INFINITY
            } else {
                gap.max(d)
            };
            n += 1;
        }
    }
    eprintln!("GPU vs twin: {n} vertices, {status:?}, max difference {gap:.2e}");
    assert_eq!(status.reached as usize, n);
    (gap, n)
}

/// The GPU relaxation reaches the CPU twin's fixed point (same seeds, same upwind tree, same
/// update): on the plane arc, the cylinder helix and a curve across Spot's back (over its UV seams
/// and curved surface), the same vertices, and coordinates and distances within 1e-5 (f32
/// sin/cos/atan2 differ in the last bits between the two; the tree is the same).
#[test]
fn gpu_relaxation_matches_the_twin() {
    let engine = common::engine();
    let arc = |topo: &Topology| {
        let pts = (0..=120)
            .map(|k| {
                let t = -PI / 3.0 + 2.0 * PI / 3.0 * k as f32 / 120.0;
                Vec3::new(0.6 * t.cos(), 0.6 * t.sin(), 0.0)
            })
            .collect();
        curve(topo, pts)
    };
    let (gap, n) = gpu_against_twin(&engine, plane(40), arc, 0.3);
    assert!(n > 300 && gap < 1e-5, "plane: {n} vertices, gap {gap:.2e}");
    let helix = |topo: &Topology| {
        let pts = (0..=300)
            .map(|k| {
                let s = 1.6 * k as f32 / 300.0;
                let (th, z) = (-0.6 + s * 0.4f32.cos(), -0.3 + s * 0.4f32.sin());
                Vec3::from(place_cpu(topo, Query::Point(Vec3::new(th.cos(), th.sin(), z))).point)
            })
            .collect();
        curve(topo, pts)
    };
    let (gap, n) = gpu_against_twin(&engine, common::cylinder(64, 32), helix, 0.35);
    assert!(
        n > 100 && gap < 1e-5,
        "cylinder: {n} vertices, gap {gap:.2e}"
    );
    let spot =
        Mesh::load(&std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/spot.glb"))
            .unwrap();
    let back = |topo: &Topology| {
        let pts = (0..=200)
            .map(|k| {
                let x = -0.2 + 0.4 * k as f32 / 200.0;
                let q = place_cpu(
                    topo,
                    Query::Ray(Vec3::new(x, 2.0, -0.2 + 0.1 * (4.0 * x).sin()), Vec3::NEG_Y),
                );
                assert!(q.found != 0, "the ray at x = {x} misses Spot");
                Vec3::from(q.point)
            })
            .collect();
        curve(topo, pts)
    };
    let (gap, n) = gpu_against_twin(&engine, spot, back, 0.12);
    assert!(n > 100 && gap < 1e-5, "spot: {n} vertices, gap {gap:.2e}");
}

/// Writes the flat grid over [−1, 1]² as a GLB whose UVs are its positions ((x + 1) / 2,
/// (1 − y) / 2), and a 16-bit image whose linear red is its x coordinate and green its y (pixel
/// centres), so a baked texel's colour says which image point it shows.
fn flat_scene(dir: &std::path::Path) {
    let m = plane(48);
    let pos: Vec<[f32; 3]> = m.positions.iter().map(|p| p.to_array()).collect();
    let uvs: Vec<[f32; 2]> = m
        .positions
        .iter()
        .map(|p| [(p.x + 1.0) / 2.0, (1.0 - p.y) / 2.0])
        .collect();
    let idx: Vec<u32> = m.triangles.iter().flatten().copied().collect();
    common::write_glb(&dir.join("plane.glb"), &pos, Some(&uvs), &idx);
    let (w, h) = (256u32, 64u32);
    let img = decalbake::io::image::LinearImage {
        width: w,
        height: h,
        pixels: (0..h)
            .flat_map(|y| {
                (0..w).map(move |x| {
                    [
                        (x as f32 + 0.5) / w as f32,
                        (y as f32 + 0.5) / h as f32,
                        0.0,
                        1.0,
                    ]
                })
            })
            .collect(),
    };
    std::fs::write(dir.join("grad.png"), img.encode_png(16)).unwrap();
}

/// The arc of radius 0.6 around the origin, θ from −π/3 to π/3, as 121 points.
fn arc_path() -> Vec<[f32; 3]> {
    (0..=120)
        .map(|k| {
            let t = -PI / 3.0 + 2.0 * PI / 3.0 * k as f32 / 120.0;
            [0.6 * t.cos(), 0.6 * t.sin(), 0.0]
        })
        .collect()
}

/// A ribbon job on the flat scene along the arc of radius 0.6 (θ from −π/3 to π/3, 121 points).
fn arc_job(dir: &std::path::Path, extra: serde_json::Value) -> decalbake::Job {
    let path = arc_path();
    let mut layer = serde_json::json!({ "kind": "ribbon", "image": "grad.png", "path": path,
        "width": 0.2 });
    for (k, v) in extra.as_object().unwrap() {
        layer[k] = v.clone();
    }
    let text = serde_json::json!({ "mesh": "plane.glb",
        "texture": { "width": 256, "height": 256, "padding": 0, "base": [0.0, 0.0, 1.0, 1.0] },
        "output": { "bit_depth": 16 },
        "layers": [layer] })
    .to_string();
    decalbake::Job::parse(&text, &dir.join("job.json"), dir, dir).unwrap()
}

/// The image point each texel of a ribbon bake shows against the analytic one. A ribbon along a
/// circular arc of radius R on the flat grid (whose UVs are its positions) maps the point at
/// radius ρ and angle θ to u = R (θ − θ0) along and v = R − ρ across the curve (Fermi
/// coordinates); the image (a gradient: red = image x, green = image y) then shows x = u / L,
/// y = 1/2 − v / w with `"repeat": "stretch"`, x = frac(u / p) (p = w × the image's aspect,
/// 256 / 64) with `"tile"`, and y = 1/2 − (v − w/2) / w for `"align": "left"`, mirrored
/// (1/2 + (v − w/2) / w) with `"flip"`. Checked at texel centres inside the strip, away from its
/// edges and the tiles' seams by a texel and a half: within 6e-3 of the image (measured 3.9e-3 to
/// 4.7e-3, the larger for the left-aligned strip, twice as far from the curve; in model units
/// under a tenth of a texel; the curve is the polyline through the 121 path points, 1° apart, so
/// it sits up to 2e-5 inside the circle). Covered texels outside the strip: none. Mirroring the
/// image's y (flip's sign left out) or tiling with a period 1 % too long fails the check.
#[test]
fn ribbon_bakes_show_the_image_at_the_fermi_coordinates() {
    let engine = common::engine();
    let dir = common::scratch("ribbon_bake");
    flat_scene(&dir);
    let (r, w, l) = (0.6f32, 0.2f32, 0.6 * 2.0 * PI / 3.0);
    let cases: [(&str, serde_json::Value); 4] = [
        ("stretch", serde_json::json!({})),
        ("tile", serde_json::json!({ "repeat": "tile" })),
        ("left", serde_json::json!({ "align": "left" })),
        (
            "left, flipped",
            serde_json::json!({ "align": "left", "flip": true }),
        ),
    ];
    for (name, extra) in cases {
        let job = arc_job(&dir, extra);
        let mesh = engine.load_mesh(&job.mesh).unwrap();
        let baked = engine.bake(&mesh, &job).unwrap();
        let texel = 2.0 / 256.0;
        let (mut worst, mut n, mut stray) = (0.0f32, 0, 0);
        for ty in 0..256u32 {
            for tx in 0..256u32 {
                let p = Vec2::new(
                    -1.0 + (tx as f32 + 0.5) * texel,
                    1.0 - (ty as f32 + 0.5) * texel,
                );
                let (rho, t) = (p.length(), p.y.atan2(p.x));
                let (u, v) = (r * (t + PI / 3.0), r - rho);
                let c = baked.linear(tx, ty);
                let painted = c[2] < 0.5;
                let (lo, hi) = match name {
                    "stretch" | "tile" => (-w / 2.0, w / 2.0),
                    _ => (0.0, w),
                };
                let margin = 1.5 * texel;
                let inside = u > margin && u < l - margin && v > lo + margin && v < hi - margin;
                let outside = u < -margin || u > l + margin || v < lo - margin || v > hi + margin;
                if outside && painted {
                    stray += 1;
                }
                if !inside {
                    continue;
                }
                let across = (v - (lo + hi) / 2.0) / w;
                let want_y = if name.ends_with("flipped") {
                    0.5 + across
                } else {
                    0.5 - across
                };
                let want_x = match name {
                    "tile" => {
                        let f = (u / (w * 4.0)).fract();
                        if !(0.03..=0.97).contains(&f) {
                            continue;
                        }
                        f
                    }
                    _ => u / l,
                };
                let e = (c[0] - want_x).abs().max((c[1] - want_y).abs());
                worst = worst.max(e);
                n += 1;
            }
        }
        eprintln!("{name}: {n} texels inside, max error {worst:.2e}, {stray} painted outside");
        assert!(n > 1000, "{name}: {n} texels checked");
        assert!(worst < 6e-3, "{name}: max error {worst:.2e}");
        assert_eq!(stray, 0, "{name}: texels painted outside the strip");
    }
}

/// Bad ribbon layers are refused with exit 2, the layer and field named, and no output written.
#[test]
fn bad_ribbons_are_refused_by_field() {
    let dir = common::scratch("ribbon_bad");
    flat_scene(&dir);
    let two = serde_json::json!([[0.0, 0.0, 0.0], [0.3, 0.0, 0.0]]);
    let cases = [
        (
            serde_json::json!({ "path": [[0.0, 0.0, 0.0]] }),
            "layers[0].path",
        ),
        (
            serde_json::json!({ "path": two, "width": -1.0 }),
            "layers[0].width",
        ),
        (
            serde_json::json!({ "path": two, "repeat": "loop" }),
            "layers[0].repeat",
        ),
        (
            serde_json::json!({ "path": two, "align": "up" }),
            "layers[0].align",
        ),
        (
            serde_json::json!({ "path": two, "size": [1.0, 1.0] }),
            "layers[0].size",
        ),
        (
            serde_json::json!({ "path": two, "method": "lscm" }),
            "layers[0].method",
        ),
        (
            serde_json::json!({ "path": two, "spacing": 0.5 }),
            "layers[0].spacing",
        ),
        (
            serde_json::json!({ "path": two, "interpolate": "cubic" }),
            "layers[0].interpolate",
        ),
        (
            serde_json::json!({ "path": [[0.0, 0.0, 5.0], [0.3, 0.0, 0.0]] }),
            "path[0]",
        ),
        // Along the grid's top border: the strip would spread 0.2 to the left (+y), the
        // surface ends 0.1 away.
        (
            serde_json::json!({ "path": [[-0.5, 0.9, 0.0], [0.0, 0.9, 0.0], [0.5, 0.9, 0.0]],
                "width": 0.4 }),
            "layers[0].width",
        ),
        (
            serde_json::json!({ "path": two, "warp": [[[0.5, 0.5], [1.2, 0.5]]] }),
            "layers[0].warp[0]",
        ),
        (
            serde_json::json!({ "path": two, "warp": [[[0.5, 0.5], [0.6, 0.5]], [[0.2, 0.2], [0.6, 0.5]]] }),
            "layers[0].warp[1]",
        ),
        // A figure of eight: the first and third segments cross at the origin, a mesh vertex.
        (
            serde_json::json!({ "path": [[-0.4, -0.2, 0.0], [0.4, 0.2, 0.0], [0.4, -0.2, 0.0],
                [-0.4, 0.2, 0.0]] }),
            "crosses or touches itself",
        ),
        // The same crossing inside a triangle (off the grid's vertices and edges).
        (
            serde_json::json!({ "path": [[-0.4, -0.19, 0.0], [0.41, 0.23, 0.0], [0.41, -0.19, 0.0],
                [-0.4, 0.23, 0.0]] }),
            "crosses or touches itself",
        ),
    ];
    for (extra, field) in cases {
        let mut layer = serde_json::json!({ "kind": "ribbon", "image": "grad.png" });
        for (k, v) in extra.as_object().unwrap() {
            layer[k] = v.clone();
        }
        let job = serde_json::json!({ "mesh": "plane.glb", "layers": [layer],
            "output": { "texture": "out.png" } });
        let path = dir.join("bad.json");
        std::fs::write(&path, job.to_string()).unwrap();
        let (code, _, err) = common::cli(&["bake", path.to_str().unwrap()]);
        assert_eq!(code, 2, "{field}: {err}");
        assert!(err.contains(field), "{field} not named: {err}");
        assert!(!dir.join("out.png").exists(), "{field}: output written");
    }
    // A decal with a ribbon's field, or a path's, is refused too.
    for (field, value) in [
        ("width", serde_json::json!(0.1)),
        ("interpolate", "linear".into()),
    ] {
        let mut layer =
            serde_json::json!({ "image": "grad.png", "at": [0.0, 0.0, 0.0], "size": [0.2, 0.2] });
        layer[field] = value;
        let job = serde_json::json!({ "mesh": "plane.glb", "layers": [layer] });
        std::fs::write(dir.join("decal.json"), job.to_string()).unwrap();
        let (code, _, err) = common::cli(&["bake", dir.join("decal.json").to_str().unwrap()]);
        assert_eq!(code, 2, "{err}");
        assert!(
            err.contains(&format!("layers[0].{field}")) && err.contains("ribbons"),
            "{err}"
        );
    }
}

/// On the unit sphere, along the equator from longitude −0.6 to 0.6 (travelling east, so N × T
/// points north): Fermi coordinates are u = longitude + 0.6 and v = latitude (the meridians are
/// the geodesics that leave the equator at right angles). The twin matches them within
/// |latitude| < 0.3 and away from the ends, the error shrinking as the icosphere is refined
/// (frequencies 8, 16, 32; measured 2.6e-3, 1.0e-3, 5.7e-4; below 1e-3 on the finest); what remains on the finest is the faceting (the mesh lies inside the
/// sphere by up to 1/(2·f²)) and the sliding step's flat reading of the offset (second order in
/// the offset times the curvature).
#[test]
fn sphere_equator_gets_latitude_and_longitude() {
    use decalbake::maps::expmap::sphere::icosphere;
    let mut errors = Vec::new();
    for f in [8u32, 16, 32] {
        let mesh = icosphere(f);
        let topo = Topology::build(&mesh, DEFAULT_WELD_TOLERANCE);
        let (l0, l1) = (-0.6f32, 0.6f32);
        let points = (0..=240)
            .map(|k| {
                let l = l0 + (l1 - l0) * k as f32 / 240.0;
                Vec3::from(place_cpu(&topo, Query::Point(Vec3::new(l.cos(), l.sin(), 0.0))).point)
            })
            .collect();
        let c = curve(&topo, points);
        let map = ribbon_cpu(&topo, &c, 0.4);
        let exact = |p: Vec3| {
            let q = p.normalize();
            let (lat, lon) = (q.z.asin(), q.y.atan2(q.x));
            (lon > l0 + 0.05 && lon < l1 - 0.05 && lat.abs() < 0.3).then_some([lon - l0, lat])
        };
        let (err, n) = max_error(&topo, &map, exact);
        eprintln!(
            "icosphere {f}: {n} vertices, max error {err:.2e} (length {})",
            map.length
        );
        assert!(n > 20, "{n} vertices checked");
        errors.push(err);
    }
    for w in errors.windows(2) {
        assert!(
            w[1] < 0.7 * w[0],
            "refinement must shrink the error: {errors:?}"
        );
    }
}

/// `decalbake param` on a ribbon layer writes its map: one row `x,y,z,distance,u,v` per vertex the
/// strip's map reaches, u along the curve from its start and v across it in model units, distance
/// = |v|. On the flat scene's arc the rows inside the span match the Fermi coordinates within 1e-4
/// (measured 1.6e-5: the 121-point polyline's arcs are the circle's). The repair is off here
/// (`curved_threshold` 1e6): the 0.2-wide strip sits at r = 1.2, the default threshold, and a
/// repaired part's u is the discrete harmonic one (7.7e-4 from the exact u).
#[test]
fn param_exports_a_ribbon_map() {
    let dir = common::scratch("ribbon_param");
    flat_scene(&dir);
    let path = arc_path();
    let job = serde_json::json!({ "mesh": "plane.glb", "layers": [
        { "kind": "ribbon", "image": "grad.png", "path": path, "width": 0.2, "curved_threshold": 1e6 }] });
    std::fs::write(dir.join("job.json"), job.to_string()).unwrap();
    let out = dir.join("ribbon.csv");
    let (code, _, err) = common::param(&dir.join("job.json"), "0", &out);
    assert_eq!(code, 0, "{err}");
    let text = std::fs::read_to_string(&out).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("x,y,z,distance,u,v"));
    let (mut worst, mut n, mut rows) = (0.0f32, 0, 0);
    for line in lines {
        let f: Vec<f32> = line.split(',').map(|x| x.parse().unwrap()).collect();
        rows += 1;
        assert!((f[3] - f[5].abs()).abs() < 1e-6, "distance is |v|: {line}");
        let (rho, t) = (f[0].hypot(f[1]), f[1].atan2(f[0]));
        if t > -PI / 3.0 + 0.05 && t < PI / 3.0 - 0.05 && (0.6 - rho).abs() < 0.1 {
            let (u, v) = (0.6 * (t + PI / 3.0), 0.6 - rho);
            worst = worst.max((f[4] - u).abs()).max((f[5] - v).abs());
            n += 1;
        }
    }
    eprintln!("param: {rows} rows, {n} inside the span, max error {worst:.2e}");
    assert!(n > 100, "{n} rows checked");
    assert!(worst < 1e-4, "max error {worst:.2e}");
}

/// The thin-plate-spline warp (`"warp"`, Schmidt et al. §6.1) on the arc ribbon of
/// [`ribbon_bakes_show_the_image_at_the_fermi_coordinates`]: an identity warp (pairs that keep
/// their points) bakes byte for byte what no warp bakes, though the GPU takes its warp branch
/// (explicit derivatives, the spline evaluated); a warp of two pairs shows, at every texel inside
/// the strip, the image point T(p) of the spline's twin (`Tps::eval`) at the texel's Fermi image
/// point p, within the unwarped bake's 6e-3; and the texel whose p is nearest a pair's `to`
/// shows its `from` (the feature moved to the target). Without the warp the texels at the targets
/// show their own points, 0.15 from `from`, so the check fails.
#[test]
fn warps_move_image_points_to_their_targets() {
    use decalbake::maps::warp::Tps;
    let mut engine = common::engine();
    // Whole triangles for every bake here: the raster clips an unwarped layer's triangles to its
    // image and margin, not a warped one's, and a clipped polygon interpolates its coordinates in
    // another order (a few 16-bit levels, bounded in `tests/demo_and_api.rs`), so byte equality
    // holds between unclipped bakes.
    engine.unclipped_raster = true;
    let dir = common::scratch("ribbon_warp");
    flat_scene(&dir);
    let bake = |extra: serde_json::Value| {
        let job = arc_job(&dir, extra);
        let mesh = engine.load_mesh(&job.mesh).unwrap();
        engine.bake(&mesh, &job).unwrap()
    };
    let plain = bake(serde_json::json!({}));
    let identity =
        bake(serde_json::json!({ "warp": [[[0.3, 0.4], [0.3, 0.4]], [[0.8, 0.5], [0.8, 0.5]]] }));
    assert!(
        plain.texels == identity.texels,
        "an identity warp changed {} texel values",
        plain
            .texels
            .iter()
            .zip(&identity.texels)
            .filter(|(a, b)| a != b)
            .count()
    );
    let pairs = [[[0.5f32, 0.5], [0.6, 0.35]], [[0.25, 0.6], [0.2, 0.75]]];
    let tps = Tps::fit(&pairs).unwrap();
    let warped = bake(serde_json::json!({ "warp": pairs }));
    let (r, w, l) = (0.6f32, 0.2f32, 0.6 * 2.0 * PI / 3.0);
    let texel = 2.0 / 256.0;
    let (mut worst, mut n) = (0.0f32, 0);
    // Per pair: the texel whose image point is nearest the target (distance, colour).
    let mut nearest = [(f32::INFINITY, [0.0f32; 4]); 2];
    for ty in 0..256u32 {
        for tx in 0..256u32 {
            let p = Vec2::new(
                -1.0 + (tx as f32 + 0.5) * texel,
                1.0 - (ty as f32 + 0.5) * texel,
            );
            let (rho, t) = (p.length(), p.y.atan2(p.x));
            let (u, v) = (r * (t + PI / 3.0), r - rho);
            let margin = 1.5 * texel;
            if !(u > margin && u < l - margin && v.abs() < w / 2.0 - margin) {
                continue;
            }
            let img = [u / l, 0.5 - v / w];
            let want = tps.eval(img);
            if !(0.0..=1.0).contains(&want[0]) || !(0.0..=1.0).contains(&want[1]) {
                continue;
            }
            let c = warped.linear(tx, ty);
            let e = (c[0] - want[0]).abs().max((c[1] - want[1]).abs());
            worst = worst.max(e);
            n += 1;
            for (k, [_, to]) in pairs.iter().enumerate() {
                let d = (img[0] - to[0]).abs().max((img[1] - to[1]).abs());
                if d < nearest[k].0 {
                    nearest[k] = (d, c);
                }
            }
        }
    }
    eprintln!("warp: {n} texels, max error {worst:.2e}, nearest to the targets {nearest:?}");
    assert!(n > 1000, "{n} texels checked");
    assert!(worst < 6e-3, "max error {worst:.2e}");
    for (k, [from, _]) in pairs.iter().enumerate() {
        // The nearest texel's image point is within half a texel's footprint (about 0.02 across
        // the strip) of the target; the spline stretches that by at most about 2 here.
        let (d, c) = nearest[k];
        let e = (c[0] - from[0]).abs().max((c[1] - from[1]).abs());
        assert!(
            e < 6e-3 + 2.0 * d,
            "pair {k}: the texel {d:.3} from the target shows {c:?}, not {from:?}"
        );
    }
}

/// The painted texels of a ribbon bake on the flat scene (blue base, the gradient has none) as
/// points of the plane: their count and centroid.
fn painted(path: &std::path::Path) -> (usize, Vec<Vec2>) {
    let img = decalbake::io::image::LinearImage::load(path).unwrap();
    let texel = 2.0 / img.width as f32;
    let pts: Vec<Vec2> = (0..img.width * img.height)
        .filter(|&i| img.pixels[i as usize][2] < 0.5)
        .map(|i| {
            let (x, y) = (i % img.width, i / img.width);
            Vec2::new(
                -1.0 + (x as f32 + 0.5) * texel,
                1.0 - (y as f32 + 0.5) * texel,
            )
        })
        .collect();
    (pts.len(), pts)
}

/// An animated ribbon (`"animate"`, Sun et al. §4.3) through the CLI, one texture per frame named
/// by `{frame:02}`. On an open straight route of length 1.6 with a piece of 0.4 over 5 frames, the
/// painted strip's centroid advances by (1.6 − 0.4) / 4 = 0.3 a frame along the route (within
/// 1.5 texels, 0.012: the strip's ends are cut at texel centres) and stays on it, each frame
/// painting the same area (within 3 %). On a closed circular route of radius 0.5 with a piece of
/// 1.0 over 4 frames, frame f's piece starts at f / 4 of the loop; the last one wraps past the
/// route's start, and its painted texels still form the one arc (their mean direction is at the
/// piece's middle, (s + 0.5) / R, within 0.02 rad). Starting each frame one step late, or not
/// wrapping, fails these checks. The open route runs along the grid's edges (y = 0), which the
/// strip-width check once refused (the right side's reach read -0.0 as the largest). Bad
/// animations exit 2 naming the field, with no frame written: no `{frame}` in the texture's name
/// (or one padded to 100 digits), 0 or 1,001 frames, `path` beside `animate`, a piece longer than
/// the route, and a route whose last piece runs along the grid's border (frames 0 and 1 are baked
/// and written, then removed when frame 2 is refused).
#[test]
fn animated_ribbons_move_along_their_route() {
    let dir = common::scratch("ribbon_animate");
    flat_scene(&dir);
    let try_run = |name: &str, texture: &str, layer: serde_json::Value| {
        let mut l = serde_json::json!({ "kind": "ribbon", "image": "grad.png", "width": 0.1 });
        for (k, v) in layer.as_object().unwrap() {
            l[k] = v.clone();
        }
        let job = serde_json::json!({ "mesh": "plane.glb",
            "texture": { "width": 256, "height": 256, "padding": 0, "base": [0.0, 0.0, 1.0, 1.0] },
            "output": { "texture": texture, "report": null },
            "layers": [l] });
        let path = dir.join(format!("{name}.json"));
        std::fs::write(&path, job.to_string()).unwrap();
        common::cli(&["bake", path.to_str().unwrap()])
    };
    let run = |name: &str, animate: serde_json::Value| {
        let texture = format!("{name}_{{frame:02}}.png");
        let (code, out, err) = try_run(name, &texture, serde_json::json!({ "animate": animate }));
        assert_eq!(code, 0, "{err}");
        out
    };
    let route: Vec<[f32; 3]> = (0..=16)
        .map(|k| [-0.8 + 0.1 * k as f32, 0.0, 0.0])
        .collect();
    let anim = |frames: u32, length: f32| serde_json::json!({ "animate": { "route": route, "frames": frames, "length": length } });
    let two = serde_json::json!([[0.0, 0.0, 0.0], [0.3, 0.0, 0.0]]);
    let mut with_path = anim(3, 0.4);
    with_path["path"] = two;
    // Frames 0 and 1 bake; the last piece runs along the grid's top border, too close for the
    // strip (refused naming `width`): the frames written before it are removed.
    let late: Vec<[f32; 3]> = [[-0.8, 0.0], [0.6, 0.0], [0.6, 0.97], [-0.8, 0.97]]
        .windows(2)
        .flat_map(|w| {
            (0..20).map(move |k| {
                let t = k as f32 / 20.0;
                [
                    w[0][0] + (w[1][0] - w[0][0]) * t,
                    w[0][1] + (w[1][1] - w[0][1]) * t,
                    0.0,
                ]
            })
        })
        .chain([[-0.8, 0.97, 0.0]])
        .collect();
    let late_fail = serde_json::json!({ "animate": { "route": late, "frames": 3, "length": 0.4 } });
    for (texture, layer, field) in [
        ("bad_{frame}.png", late_fail, "layers[0].width"),
        ("bad_{frame:0100}.png", anim(3, 0.4), "output.texture"),
        ("bad.png", anim(3, 0.4), "output.texture"),
        ("bad_{frame}.png", anim(0, 0.4), "layers[0].animate.frames"),
        (
            "bad_{frame}.png",
            anim(1001, 0.4),
            "layers[0].animate.frames",
        ),
        ("bad_{frame}.png", with_path, "layers[0].path"),
        ("bad_{frame}.png", anim(3, 1.7), "layers[0].animate.length"),
    ] {
        let (code, _, err) = try_run("bad", texture, layer);
        assert_eq!(code, 2, "{field}: {err}");
        assert!(err.contains(field), "{field} not named: {err}");
        let left: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .filter_map(|e| e.ok())
            .filter(|e| {
                e.file_name().to_string_lossy().starts_with("bad") && e.file_name() != "bad.json"
            })
            .collect();
        assert!(left.is_empty(), "{field}: outputs written: {left:?}");
    }
    let out = run(
        "open",
        serde_json::json!({ "route": route, "frames": 5, "length": 0.4 }),
    );
    assert_eq!(out.lines().count(), 5, "one texture a frame: {out}");
    let mut counts = Vec::new();
    for f in 0..5 {
        let (n, pts) = painted(&dir.join(format!("open_{f:02}.png")));
        let c = pts.iter().copied().sum::<Vec2>() / n as f32;
        let want = -0.8 + 0.3 * f as f32 + 0.2;
        eprintln!("open frame {f}: {n} texels, centroid {c:?} (want x {want})");
        assert!(
            (c.x - want).abs() < 0.012 && c.y.abs() < 0.012,
            "frame {f}: centroid {c:?}, want x {want}"
        );
        counts.push(n as f32);
    }
    let mean = counts.iter().sum::<f32>() / 5.0;
    assert!(
        counts.iter().all(|n| (n / mean - 1.0).abs() < 0.03),
        "areas {counts:?}"
    );

    let r = 0.5f32;
    let circle: Vec<[f32; 3]> = (0..48)
        .map(|k| {
            let t = 2.0 * PI * k as f32 / 48.0;
            [r * t.cos(), r * t.sin(), 0.0]
        })
        .collect();
    let total: f32 = (0..48)
        .map(|k| {
            let a = Vec2::from_slice(&circle[k][..2]);
            let b = Vec2::from_slice(&circle[(k + 1) % 48][..2]);
            (b - a).length()
        })
        .sum();
    run(
        "loop",
        serde_json::json!({ "route": circle, "frames": 4, "length": 1.0, "closed": true }),
    );
    for f in 0..4 {
        let (n, pts) = painted(&dir.join(format!("loop_{f:02}.png")));
        let dir_sum: Vec2 = pts.iter().map(|p| p.normalize()).sum();
        let got = dir_sum.y.atan2(dir_sum.x).rem_euclid(2.0 * PI);
        // The middle of the piece along the polygon, as an angle (the polygon's arc is its
        // perimeter's share, so scale by 2π / perimeter).
        let want = ((total * f as f32 / 4.0 + 0.5) * 2.0 * PI / total).rem_euclid(2.0 * PI);
        let e = (got - want).abs().min(2.0 * PI - (got - want).abs());
        eprintln!("loop frame {f}: {n} texels, mean direction {got:.4} rad (want {want:.4})");
        assert!(
            n > 500 && e < 0.02,
            "frame {f}: {n} texels at {got:.4} rad, want {want:.4}"
        );
    }
}

/// `decalbake batch` writes an animated job's frames as it bakes them (none is held back for the
/// others), byte for byte what `decalbake bake` writes, and a job whose third frame fails leaves
/// nothing: the two frames written before it and the job's output folder are taken back (the
/// batch's promise that a failed job leaves no output directory).
#[test]
fn a_batch_writes_animated_frames_and_takes_them_back_when_one_fails() {
    let dir = common::scratch("ribbon_batch_frames");
    flat_scene(&dir);
    let route = |pts: &[[f32; 2]]| -> Vec<[f32; 3]> {
        pts.windows(2)
            .flat_map(|w| {
                let (a, b) = (w[0], w[1]);
                (0..20).map(move |k| {
                    let t = k as f32 / 20.0;
                    [a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t, 0.0]
                })
            })
            .chain(pts.last().map(|p| [p[0], p[1], 0.0]))
            .collect()
    };
    let job = |name: &str, pts: &[[f32; 2]]| {
        let animate = serde_json::json!({ "route": route(pts), "frames": 3, "length": 0.4 });
        let job = serde_json::json!({ "mesh": "plane.glb",
            "texture": { "width": 128, "height": 128, "padding": 0, "base": [0.0, 0.0, 1.0, 1.0] },
            "output": { "texture": format!("{name}_{{frame}}.png"), "report": null },
            "layers": [{ "kind": "ribbon", "image": "grad.png", "width": 0.1, "animate": animate }] });
        let path = dir.join(format!("{name}.json"));
        std::fs::write(&path, job.to_string()).unwrap();
        path
    };
    let good = job("good", &[[-0.8, 0.0], [0.6, 0.0]]);
    // The last piece runs along the top border, too close for the strip: frame 2 fails.
    let late = job(
        "late",
        &[[-0.8, 0.0], [0.6, 0.0], [0.6, 0.97], [-0.8, 0.97]],
    );
    let manifest = dir.join("frames.jsonl");
    let line = |p: &std::path::Path| serde_json::json!(p.to_str().unwrap()).to_string();
    let lines = format!("{}\n{}\n", line(&good), line(&late));
    std::fs::write(&manifest, lines).unwrap();
    let out = dir.join("out");
    let (code, _, err) = common::cli(&[
        "batch",
        manifest.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 3, "the second job fails: {err}");
    assert!(
        !out.join("line-2-late").exists(),
        "a failed animated job leaves no frames and no folder"
    );
    let serial = dir.join("serial");
    let (code, _, err) = common::cli(&[
        "bake",
        good.to_str().unwrap(),
        "--out",
        serial.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    for f in 0..3 {
        let name = format!("good_{f}.png");
        let batch = std::fs::read(out.join("line-1-good").join(&name));
        assert!(batch.is_ok(), "frame {f} written by the batch");
        assert_eq!(
            batch.unwrap(),
            std::fs::read(serial.join(&name)).unwrap(),
            "frame {f}: the batch writes what bake writes"
        );
    }
}

/// Texture extraction (`decalbake extract`, Sun et al. §4.2) along the arc ribbon of
/// [`ribbon_bakes_show_the_image_at_the_fermi_coordinates`].
///
/// - **Round trip**: the gradient baked along the ribbon (16-bit, 256²) and extracted along the same
///   ribbon at the image's own size returns the image: every pixel at least two texels inside the
///   strip within 6e-3 (the bake's own tolerance: both resamplings are bilinear, exact on a
///   linear gradient, so what remains is the map's error; measured 8.8e-4). Reading the strip
///   mirrored (y flipped) is off by 0.8. A layer that does not exist exits 2 naming `--layer`,
///   with no output.
/// - **GPU against its twin** (`extract_cpu`): the same pixels covered but for a few on triangle
///   edges (at most 1 %), and their colours within 1e-4 (f32 interpolation).
/// - **Matte**: a texture of a red disc on green under the strip; `--matte` gives alpha above 0.9
///   on the disc and below 0.1 on the green, a texture texel and two pixels from the disc's edge
///   (with the initial alpha's scale at the 90th percentile instead of the 99th, the disc's 5 %
///   of the strip set the scale to nothing and the green reached 0.5); the GPU solve is
///   within 1e-3 of the f64 twin (`solve_cpu`) at every pixel.
#[test]
fn extract_returns_the_baked_image_and_mattes_a_feature() {
    use decalbake::io::image::LinearImage;
    use decalbake::output::{extract, matte};
    let engine = common::engine();
    let dir = common::scratch("ribbon_extract");
    flat_scene(&dir);
    let job = arc_job(&dir, serde_json::json!({}));
    let mesh = engine.load_mesh(&job.mesh).unwrap();
    let baked = engine.bake(&mesh, &job).unwrap();
    std::fs::write(dir.join("rt.png"), baked.to_png()).unwrap();
    // The same job with the baked texture as its base.
    let path = arc_path();
    let with_base = serde_json::json!({ "mesh": "plane.glb",
        "texture": { "width": 256, "height": 256, "padding": 0, "base": "rt.png" },
        "layers": [{ "kind": "ribbon", "image": "grad.png", "path": path, "width": 0.2 }] });
    let jpath = dir.join("extract.json");
    std::fs::write(&jpath, with_base.to_string()).unwrap();
    let out = dir.join("patch.png");
    let (code, _, err) = common::cli(&[
        "extract",
        jpath.to_str().unwrap(),
        "--layer",
        "0",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let patch = LinearImage::load(&out).unwrap();
    assert_eq!(
        (patch.width, patch.height),
        (256, 64),
        "the image's own size by default"
    );
    let (mut worst, mut flipped) = (0.0f32, 0.0f32);
    for y in 6..58u32 {
        for x in 4..252u32 {
            let p = patch.pixels[(y * 256 + x) as usize];
            let want = [(x as f32 + 0.5) / 256.0, (y as f32 + 0.5) / 64.0];
            worst = worst.max((p[0] - want[0]).abs().max((p[1] - want[1]).abs()));
            flipped = flipped.max((p[1] - (1.0 - want[1])).abs());
            assert!(p[3] > 0.99, "pixel ({x}, {y}) not covered");
        }
    }
    eprintln!("round trip: max error {worst:.2e} (mirrored: {flipped:.2})");
    assert!(worst < 6e-3, "round trip off by {worst:.2e}");
    assert!(flipped > 0.5);
    let bad = dir.join("bad.png");
    let (code, _, err) = common::cli(&[
        "extract",
        jpath.to_str().unwrap(),
        "--layer",
        "3",
        "--out",
        bad.to_str().unwrap(),
    ]);
    assert!(code == 2 && err.contains("--layer 3"), "{code}: {err}");
    assert!(!bad.exists());

    // The GPU against its twin.
    let ejob = decalbake::Job::load(&jpath, None).unwrap();
    let emesh = engine.load_mesh(&ejob.mesh).unwrap();
    let flat = extract::flat_triangles(&engine, &emesh, &ejob, 0).unwrap();
    let tex = extract::source_texture(&engine, &emesh, &ejob).unwrap();
    let gpu = extract::extract_gpu(&engine, &flat, &tex, [256, 64]).unwrap();
    let cpu = extract::extract_cpu(&flat, &tex, [256, 64]);
    let (mut differ, mut diff) = (0, 0.0f32);
    for (g, c) in gpu.pixels.iter().zip(&cpu.pixels) {
        if (g[3] > 0.0) != (c[3] > 0.0) {
            differ += 1;
        } else if g[3] > 0.0 {
            diff = diff.max((0..4).map(|k| (g[k] - c[k]).abs()).fold(0.0, f32::max));
        }
    }
    eprintln!("extract GPU vs twin: {differ} pixels covered by one only, max colour difference {diff:.1e}");
    assert!(
        differ <= 256 * 64 / 100 && diff < 1e-4,
        "{differ} pixels, {diff:.1e}"
    );

    // The matte: a red disc on green, centred under the strip's middle.
    let centre = Vec2::new(0.6, 0.0);
    let base = LinearImage {
        width: 256,
        height: 256,
        pixels: (0..256 * 256)
            .map(|i| {
                let p = Vec2::new(
                    -1.0 + (i % 256) as f32 / 128.0 + 1.0 / 256.0,
                    1.0 - (i / 256) as f32 / 128.0 - 1.0 / 256.0,
                );
                if (p - centre).length() < 0.06 {
                    [0.8, 0.05, 0.05, 1.0]
                } else {
                    [0.1, 0.5, 0.1, 1.0]
                }
            })
            .collect(),
    };
    let flat_tex = extract::extract_gpu(&engine, &flat, &base, [256, 64]).unwrap();
    let sys = matte::system(&flat_tex);
    let (ga, rep) = matte::solve_gpu(&engine, &sys).unwrap();
    let (ca, _) = matte::solve_cpu(&sys);
    let gap = ga
        .iter()
        .zip(&ca)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    let mut matted = flat_tex.clone();
    matte::apply(&mut matted, &sys, &ga);
    // Pixel → plane point: the strip's Fermi coordinates back to the plane.
    let (l, w) = (0.6 * 2.0 * PI / 3.0, 0.2);
    let (mut inside, mut outside) = (f32::INFINITY, 0.0f32);
    for y in 0..64u32 {
        for x in 0..256u32 {
            let (u, v) = (
                (x as f32 + 0.5) / 256.0 * l,
                (0.5 - (y as f32 + 0.5) / 64.0) * w,
            );
            let t = u / 0.6 - PI / 3.0;
            let p = Vec2::new(t.cos(), t.sin()) * (0.6 - v);
            let d = (p - centre).length();
            let a = matted.pixels[(y * 256 + x) as usize][3];
            // The texture's bilinear filter blurs the disc's edge over a texel (2 / 256), and
            // two pixels across the strip are 2 × 0.2 / 64.
            let margin = 2.0 / 256.0 + 0.00625;
            if d < 0.06 - margin {
                inside = inside.min(a);
            } else if d > 0.06 + margin {
                outside = outside.max(a);
            }
        }
    }
    eprintln!("matte: {} unknowns, CG {} iterations, GPU vs twin {gap:.1e}; alpha on the disc >= {inside:.3}, off it <= {outside:.3}", sys.b.len(), rep.iterations);
    assert!(
        inside > 0.9 && outside < 0.1,
        "matte: {inside} on the disc, {outside} off it"
    );
    assert!(gap < 1e-3, "GPU matte off the twin by {gap:.1e}");
}

/// The turn of [`tight_turn_repair`]: along y = 0 to x = 0, a quarter circle of radius 0.1 turning
/// left (centre (0, 0.1)), then up along x = 0.1; points every 0.01 or so.
fn tight_turn() -> Vec<[f32; 3]> {
    let mut p: Vec<[f32; 3]> = (0..=70)
        .map(|k| [-0.7 + 0.01 * k as f32, 0.0, 0.0])
        .collect();
    for k in 1..=16 {
        let t = -std::f32::consts::FRAC_PI_2 + std::f32::consts::FRAC_PI_2 * k as f32 / 16.0;
        p.push([0.1 * t.cos(), 0.1 + 0.1 * t.sin(), 0.0]);
    }
    p.extend((1..=60).map(|k| [0.1, 0.1 + 0.01 * k as f32, 0.0]));
    p
}

/// Harmonic repair (Sun et al. §3 steps 4-5) of a curve on the flat grid that turns left with a
/// radius of 0.1 under a strip 0.3 wide: inside the turn the offsets collapse (half-width 0.15 >
/// 0.1). With the repair off (`curved_threshold` 1e6) the map folds there (the report's
/// `distortion.flipped` counts the layer's flipped triangles); with the default λ = 0.2 no
/// triangle flips, the report names the part repaired (an arc-length range containing the turn,
/// 0.7 to 0.857) and that re-solving u alone was not enough there (`rectangle`: the full harmonic
/// map onto the rectangle). The GPU solve is within 1e-4 of the f64
/// twin's (`repair::solve_cpu`) on the same map (the CG's f32 stopping point; the coordinates are
/// in model units, 0.3 across).
#[test]
fn tight_turns_are_repaired_harmonically() {
    use decalbake::maps::ribbon::repair::{curved_parts, repair, solve_cpu, solve_gpu};
    let engine = common::engine();
    let dir = common::scratch("ribbon_repair");
    flat_scene(&dir);
    let bake = |extra: serde_json::Value| {
        let mut layer = serde_json::json!({ "kind": "ribbon", "image": "grad.png", "path": tight_turn(), "width": 0.3 });
        for (k, v) in extra.as_object().unwrap() {
            layer[k] = v.clone();
        }
        let text = serde_json::json!({ "mesh": "plane.glb",
            "texture": { "width": 256, "height": 256, "padding": 0, "base": [0.0, 0.0, 1.0, 1.0] },
            "output": { "bit_depth": 16 }, "layers": [layer] })
        .to_string();
        let job = decalbake::Job::parse(&text, &dir.join("job.json"), &dir, &dir).unwrap();
        let mesh = engine.load_mesh(&job.mesh).unwrap();
        engine.bake(&mesh, &job).unwrap()
    };
    let off = bake(serde_json::json!({ "curved_threshold": 1e6 }));
    let on = bake(serde_json::json!({}));
    let (lo, ro) = (&off.report.layers[0], &on.report.layers[0]);
    let rep = ro.ribbon.as_ref().expect("a ribbon reports its repair");
    eprintln!(
        "repair off: {} flipped; on: {} flipped, repaired {:?} ({} vertices, {} CG iterations)",
        lo.distortion.flipped, ro.distortion.flipped, rep.repaired, rep.vertices, rep.cg_iterations
    );
    assert!(lo.distortion.flipped > 0, "the unrepaired turn should fold");
    assert!(lo.ribbon.as_ref().unwrap().repaired.is_empty());
    assert_eq!(ro.distortion.flipped, 0, "the repaired map folds");
    std::fs::write(dir.join("off.png"), off.to_png()).unwrap();
    std::fs::write(dir.join("on.png"), on.to_png()).unwrap();
    assert!(
        rep.repaired.iter().any(|r| r[0] <= 0.7 && r[1] >= 0.857),
        "{:?}",
        rep.repaired
    );

    // GPU solve against the twin on the CPU twin's map.
    let m = plane(48);
    let topo = Topology::build(&m, DEFAULT_WELD_TOLERANCE);
    let c = curve(&topo, tight_turn().iter().map(|p| Vec3::from(*p)).collect());
    let map = ribbon_cpu(&topo, &c, 0.2);
    let uv: Vec<Option<[f32; 2]>> = (0..topo.positions.len())
        .map(|v| map.reached(v).then(|| map.uv[v]))
        .collect();
    let parts = curved_parts(&topo, &c, [0.15, 0.15], 0.2);
    assert!(!parts.is_empty());
    let (mut a, mut b) = (uv.clone(), uv.clone());
    let twin = repair(&topo, &mut a, &parts, solve_cpu).unwrap();
    assert!(
        !twin.repaired.is_empty(),
        "the twin repaired nothing: {twin:?}"
    );
    repair(
        &topo,
        &mut b,
        &parts,
        solve_gpu(&engine.ctx, engine.pipelines()),
    )
    .unwrap();
    let gap = a
        .iter()
        .zip(&b)
        .filter_map(|(x, y)| Some((x.as_ref()?, y.as_ref()?)))
        .map(|(x, y)| (x[0] - y[0]).abs().max((x[1] - y[1]).abs()))
        .fold(0.0f32, f32::max);
    let changed = uv.iter().zip(&a).filter(|(x, y)| x != y).count();
    assert!(changed > 50, "the repair changed {changed} vertices");
    eprintln!("repair GPU vs twin: {gap:.1e} over {changed} changed vertices");
    assert!(gap < 1e-4, "GPU repair off the twin by {gap:.1e}");
}

/// Curve editing (Sun et al. §4.4) is re-baking with moved path points, and it is continuous: the
/// arc ribbon (0.1 wide here: no part curved enough to repair, r = 1.09; a repaired part is
/// re-solved as a whole, so an edit inside it moves the whole part, by up to 3.6e-3 in the 0.2-wide
/// strip) baked again with its middle point (of 121) moved 0.001 towards the arc's centre
/// changes no texel by more than 2e-3 (half an 8-bit step) farther than the strip's half-width
/// plus three texels from that point, and none by more than 0.02 anywhere (texels the strip's
/// edge crosses in either bake are left out: there any move takes samples in or out; the gradient image
/// shows the image point: near the point v moves by up to 0.001, 0.01 of the image across the
/// strip; everywhere else only the curve's length changes, by 1e-4, moving u by under 1e-4 of the
/// image). Some texel near the point changes by more than 1e-3, so the check sees the edit.
#[test]
fn editing_a_path_point_changes_the_texture_only_near_it() {
    let engine = common::engine();
    let dir = common::scratch("ribbon_edit");
    flat_scene(&dir);
    let bake = |moved: f32| {
        let path: Vec<[f32; 3]> = (0..=120)
            .map(|k| {
                let t = -PI / 3.0 + 2.0 * PI / 3.0 * k as f32 / 120.0;
                let r = if k == 60 { 0.6 - moved } else { 0.6 };
                [r * t.cos(), r * t.sin(), 0.0]
            })
            .collect();
        let text = serde_json::json!({ "mesh": "plane.glb",
            "texture": { "width": 256, "height": 256, "padding": 0, "base": [0.0, 0.0, 1.0, 1.0] },
            "output": { "bit_depth": 16 },
            "layers": [{ "kind": "ribbon", "image": "grad.png", "path": path, "width": 0.1 }] })
        .to_string();
        let job = decalbake::Job::parse(&text, &dir.join("job.json"), &dir, &dir).unwrap();
        let mesh = engine.load_mesh(&job.mesh).unwrap();
        engine.bake(&mesh, &job).unwrap()
    };
    let (a, b) = (bake(0.0), bake(0.001));
    for x in [&a, &b] {
        let rep = x.report.layers[0].ribbon.as_ref().unwrap();
        assert!(
            rep.repaired.is_empty(),
            "the strip is not curved enough to repair: {rep:?}"
        );
    }
    let point = Vec2::new(0.6, 0.0);
    let texel = 2.0 / 256.0;
    let (mut far, mut most, mut near) = (0.0f32, 0.0f32, 0.0f32);
    for ty in 0..256u32 {
        for tx in 0..256u32 {
            let p = Vec2::new(
                -1.0 + (tx as f32 + 0.5) * texel,
                1.0 - (ty as f32 + 0.5) * texel,
            );
            let (ca, cb) = (a.linear(tx, ty), b.linear(tx, ty));
            let d = (0..4).map(|k| (ca[k] - cb[k]).abs()).fold(0.0, f32::max);
            // Texels the strip's edge crosses in either bake: a move of 1e-4 there can take a
            // sample in or out (a quarter of the texel each, 4 samples); checked whole elsewhere.
            let whole = |c: [f32; 4]| c[2] < 1e-3 || c[2] > 1.0 - 1e-3;
            if !(whole(ca) && whole(cb)) {
                continue;
            }
            most = most.max(d);
            if (p - point).length() > 0.05 + 3.0 * texel {
                far = far.max(d);
            } else {
                near = near.max(d);
            }
        }
    }
    eprintln!("edit: largest change {most:.2e}, near the point {near:.2e}, farther {far:.2e}");
    assert!(far < 2e-3, "a far texel changed by {far:.2e}");
    assert!(most < 0.02, "a texel changed by {most:.2e}");
    assert!(
        near > 1e-3,
        "the edit changed nothing near the point ({near:.2e})"
    );
}

/// The whole bake's CPU twin (`bake::cpu::bake_units_cpu` with the ribbon units of
/// `Engine::units`: the curve map's twin, the repair's f64 twin, the raster's repeat) against the
/// GPU bake of the arc ribbon, stretched and tiled: every texel whose four samples the strip covers
/// in both (the GPU samples the gradient's mipmaps, the twin level 0: the same linear function
/// away from the image's borders, so texels within two texels of the strip's edges, ends and tile
/// seams are left out) within 1e-4, as the decal bakes in `tests/compose_vs_cpu.rs` (measured
/// 1.7e-5 and 1.8e-5: the maps differ by up to 1e-5 model units, the 16-bit read-back by 1.5e-5).
/// Reading the twin's tiles with one copy fewer fails the tiled case.
#[test]
fn ribbon_bakes_match_the_whole_bake_twin() {
    use decalbake::bake::cpu::bake_units_cpu;
    use decalbake::io::image::LinearImage;
    let engine = common::engine();
    let dir = common::scratch("ribbon_twin");
    flat_scene(&dir);
    let grad = LinearImage::load(&dir.join("grad.png")).unwrap();
    let (r, w, l) = (0.6f32, 0.2f32, 0.6 * 2.0 * PI / 3.0);
    for (name, extra) in [
        ("stretch", serde_json::json!({})),
        ("tile", serde_json::json!({ "repeat": "tile" })),
    ] {
        let job = arc_job(&dir, extra);
        let mesh = engine.load_mesh(&job.mesh).unwrap();
        let baked = engine.bake(&mesh, &job).unwrap();
        let units = engine.units(&mesh, &job).unwrap();
        let images: Vec<_> = units.origin.iter().map(|_| (grad.clone(), None)).collect();
        let base = LinearImage::solid(1, 1, [0.0, 0.0, 1.0, 1.0]);
        let cpu = bake_units_cpu(
            &mesh.mesh,
            &mesh.topo,
            (&units.job, &units.placements, &units.frames),
            (&units.strokes, &units.ribbons),
            &base,
            &images,
        );
        let texel = 2.0 / 256.0;
        let (mut worst, mut n) = (0.0f32, 0);
        for ty in 0..256u32 {
            for tx in 0..256u32 {
                let p = Vec2::new(
                    -1.0 + (tx as f32 + 0.5) * texel,
                    1.0 - (ty as f32 + 0.5) * texel,
                );
                let (u, v) = (r * (p.y.atan2(p.x) + PI / 3.0), r - p.length());
                let m = 2.0 * texel;
                if !(u > m && u < l - m && v.abs() < w / 2.0 - m) {
                    continue;
                }
                if name == "tile" {
                    let f = (u / (w * 4.0)).fract();
                    if !(0.05..=0.95).contains(&f) {
                        continue;
                    }
                }
                let (g, c) = (
                    baked.linear(tx, ty),
                    cpu.composed.pixels[(ty * 256 + tx) as usize],
                );
                worst = worst.max((0..3).map(|k| (g[k] - c[k]).abs()).fold(0.0, f32::max));
                n += 1;
            }
        }
        eprintln!("{name}: {n} texels, max |GPU - twin| {worst:.2e}");
        assert!(n > 1000 && worst < 1e-4, "{name}: {n} texels, {worst:.2e}");
    }
}
