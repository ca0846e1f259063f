// SPDX-License-Identifier: MIT OR Apache-2.0
//! A layer's local coordinates, one module per map method behind one interface ([`MapMethod`]).
//!
//! What every method produces: for each welded vertex, `vec4(x, y, extra, valid)` in the layer's
//! slot of the bake's coords buffer, with `(x, y)` in model units in the layer's [`Frame`] (image
//! centre at the origin, image +x and +y along the frame's axes) and `valid` > 0.5 where the map
//! reaches; plus the method's report block (the exponential map's sweeps and reach, the chart's
//! solve). The bake's selection stage then keeps the triangles whose three vertices are valid and
//! whose coordinate box meets the decal rectangle; the raster stage samples the image at `(x, y)`.
//!
//! The bake's map stage (`src/bake/maps.rs`) computes a chunk of layers in three shared, batched
//! passes, and a method says which of them produce its coordinates:
//! 1. the **exponential-map pass** ([`MapMethod::uses_expmap`]): one GPU dispatch for every layer of
//!    the chunk that needs the geodesic map around its point (the result for `expmap`, the warm
//!    start for `lscm`, the map to repair for `hybrid`);
//! 2. the **chart pass** ([`MapMethod::chart`]): every conformal chart of the chunk solved in one
//!    batched GPU conjugate gradient;
//! 3. the **direct pass** ([`MapMethod::record`]): methods with a closed form record their own
//!    kernel (planar).
//!
//! Adding a method: a module here implementing [`MapMethod`], its name in `io::job::Method` (parse
//! and enum) and one line in [`method`]. A method that fits none of the passes adds a pass to
//! `src/bake/maps.rs`.
pub mod chart;
pub mod distortion;
pub mod expmap;
mod frame;
pub mod hybrid;
pub mod lscm;
pub mod planar;
pub mod ribbon;
pub mod stamp;
pub mod warp;

pub use frame::Frame;

use crate::gpu::pipelines::Pipelines;
use crate::io::job::{Layer, Method};
use crate::mesh::{SurfaceRef, Topology};
use chart::ChartRequest;

/// The resources a method's own kernel binds in the direct pass.
pub struct Record<'a> {
    /// The device (bind groups).
    pub device: &'a wgpu::Device,
    /// The engine's pipelines.
    pub pipes: &'a Pipelines,
    /// The welded surface.
    pub mesh: SurfaceRef<'a>,
    /// The chunk's per-layer `Params` block (bound at a dynamic offset per layer).
    pub params: wgpu::BindingResource<'a>,
    /// The chunk's coords buffer (one slot of `vertex_count` vec4 per layer).
    pub coords: &'a wgpu::Buffer,
}

/// How a layer's local coordinates are computed: which of the map stage's passes produce them, and
/// the same on the CPU (the twin the tests compare against).
pub trait MapMethod: Sync {
    /// Only triangles facing the frame's normal (within the layer's `depth`) are covered: true for
    /// projections, which would otherwise paint through the model.
    fn front_facing(&self) -> bool {
        false
    }

    /// The layer's exponential map is computed in the batched exponential-map pass (and handed to
    /// [`MapMethod::chart`]).
    fn uses_expmap(&self) -> bool {
        false
    }

    /// The layer's coordinates come from a conformal chart solved in the batched chart pass.
    fn solves_chart(&self) -> bool {
        false
    }

    /// The conformal chart to solve for this layer in the batched chart pass, from its exponential
    /// map; `None` for methods without one.
    fn chart<'a>(
        &self,
        _layer: &Layer,
        _frame: Frame,
        _triangle: u32,
        _expmap: &'a [[f32; 4]],
    ) -> Option<ChartRequest<'a>> {
        None
    }

    /// Records the method's own coordinate kernel in the direct pass, one dispatch per layer
    /// (`offsets`: each layer's `Params` offset); returns the dispatches recorded.
    fn record(&self, _cx: &Record<'_>, _pass: &mut wgpu::ComputePass<'_>, _offsets: &[u32]) -> u32 {
        0
    }

    /// The vertices the selection stage needs to look at for a layer of this method placed with
    /// `frame`, when the method's own pass writes every vertex (planar: those near the decal's box,
    /// from the mesh's BVH, [`planar::reach`]); `None`: the whole mesh. Methods built on the
    /// exponential map get their reach from the map stage instead.
    fn reach(
        &self,
        _topo: &Topology,
        _bvh: &crate::mesh::bvh::Bvh,
        _frame: &Frame,
    ) -> Option<Vec<u32>> {
        None
    }

    /// CPU twin: the layer's coordinates for every welded vertex. `expmap` is the layer's CPU
    /// exponential map when [`MapMethod::uses_expmap`]; `cone`: whether a chart may be opened at a
    /// tip ([`chart::ChartRequest::cone`]). The default serves the methods built on the
    /// exponential map: the chart solved in f64 from it, or the map itself.
    fn cpu_coords(
        &self,
        topo: &Topology,
        layer: &Layer,
        frame: &Frame,
        at: (u32, bool),
        expmap: Option<Vec<[f32; 4]>>,
    ) -> CpuCoords {
        let map = expmap.expect("the exponential map is computed for methods that use it");
        if self.solves_chart() {
            cpu_chart_coords(self, topo, layer, frame, at, map)
        } else {
            CpuCoords {
                coords: map,
                cone: None,
            }
        }
    }
}

/// A layer's coordinates from a CPU twin: what its slot holds, and the cone transform its chart
/// goes through where the coordinates are used ([`chart::cone`]).
#[derive(Debug, Clone)]
pub struct CpuCoords {
    /// Per welded vertex `(x, y, extra, valid)`.
    pub coords: Vec<[f32; 4]>,
    /// The chart's cone, when it was opened at a tip.
    pub cone: Option<chart::cone::Cone>,
}

/// The one place where a job's `method` becomes its implementation.
pub fn method(m: Method) -> &'static dyn MapMethod {
    match m {
        Method::Planar => &planar::Planar,
        Method::Expmap => &expmap::Expmap,
        Method::Lscm => &lscm::Lscm,
        Method::Hybrid => &hybrid::Hybrid,
        Method::Ribbon => &ribbon::RibbonMethod,
    }
}

/// CPU twin of a chart method's coordinates: the chart solved in f64 from `expmap`, written over a
/// zero slot, or over the exponential map when the method keeps it.
fn cpu_chart_coords<M: MapMethod + ?Sized>(
    m: &M,
    topo: &Topology,
    layer: &Layer,
    frame: &Frame,
    (triangle, cone): (u32, bool),
    expmap: Vec<[f32; 4]>,
) -> CpuCoords {
    let req = ChartRequest {
        cone,
        ..m.chart(layer, *frame, triangle, &expmap)
            .expect("a chart method returns a chart")
    };
    let solved = chart::build(topo, &[req], &chart::Solver::Cpu, &mut Default::default())
        .expect("the CPU solver does not fail")
        .remove(0);
    let mut coords = if !solved.replaces_map {
        expmap
    } else {
        vec![[0.0; 4]; topo.positions.len()]
    };
    let cone = solved.cone();
    for (v, c) in solved.coords {
        coords[v as usize] = [c[0], c[1], 0.0, 1.0];
    }
    CpuCoords { coords, cone }
}
