// SPDX-License-Identifier: MIT OR Apache-2.0
//! The JSON report written next to a bake.

use crate::maps::Frame;
use crate::place::Placement;
use serde::Serialize;

/// Mesh statistics, as `decalbake info` prints them.
#[derive(Debug, Clone, Serialize)]
pub struct MeshStats {
    /// Source file.
    pub source: String,
    /// Primitives in the scene.
    pub primitives: Vec<crate::mesh::PrimitiveInfo>,
    /// glTF (split) vertices.
    pub vertices: usize,
    /// Welded vertices.
    pub welded_vertices: usize,
    /// Triangles.
    pub triangles: usize,
    /// Degenerate triangles (skipped).
    pub degenerate_triangles: usize,
    /// UV sets (each on some primitive; `primitives[i].uv_sets` says which a primitive has).
    pub uv_sets: usize,
    /// The texture sets on `TEXCOORD_0` (`crate::mesh::TextureSet`: one texture each).
    pub texture_sets: Vec<crate::mesh::TextureSet>,
    /// Boundary edges.
    pub boundary_edges: usize,
    /// Non-manifold edges.
    pub non_manifold_edges: usize,
    /// Connected components.
    pub components: u32,
    /// Bounding box min.
    pub bbox_min: [f32; 3],
    /// Bounding box max.
    pub bbox_max: [f32; 3],
    /// Welding distance used (model units).
    pub weld_distance: f32,
    /// Whether the material has a base-colour texture.
    pub has_base_color_texture: bool,
}

/// Per-layer results.
#[derive(Debug, Clone, Serialize)]
pub struct LayerReport {
    /// Index in the job.
    pub index: usize,
    /// The layer's kind.
    pub kind: crate::io::job::LayerKind,
    /// Image path.
    pub image: String,
    /// Method.
    pub method: crate::io::job::Method,
    /// Blend mode.
    pub blend: crate::io::job::BlendMode,
    /// Where it landed.
    pub placement: Placement,
    /// How far the requested point moved to reach the surface (for a ray: distance along it).
    pub distance_moved: f32,
    /// The decal frame.
    pub frame: Frame,
    /// Triangles the layer covers.
    pub triangles_covered: u32,
    /// Texels the layer changed.
    pub texels_covered: u32,
    /// Texel bounding box (min x, min y, max x, max y) before UV wrapping.
    pub texel_box: [i32; 4],
    /// Distortion of the layer's map over the triangles it covers.
    pub distortion: crate::maps::distortion::Distortion,
    /// Of the triangles the bake draws for the layer (every stamp of a stroke, summed), those
    /// whose map is flipped (`distortion.flipped`): a warning names the layer when any of the
    /// three footprint counts is not zero.
    pub footprint_flipped: u32,
    /// Of those, collapsed (`distortion.collapsed`).
    pub footprint_collapsed: u32,
    /// Of those, torn (`distortion.torn`).
    pub footprint_torn: u32,
    /// Exponential-map layers (and lscm / hybrid, which start from one): relaxation sweeps,
    /// vertices and triangles reached, convergence.
    pub expmap: Option<crate::maps::expmap::gpu::GeoResult>,
    /// LSCM / hybrid: the conformal chart's solve (triangles, rounds, CG iterations, residual, status).
    pub chart: Option<crate::maps::chart::ChartReport>,
    /// Ribbons: the harmonic repair of the strip's highly curved parts (Sun et al. §3 steps 4-5):
    /// `repaired` and `skipped` arc-length ranges along the curve, `vertices`, `cg_iterations`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ribbon: Option<crate::maps::ribbon::repair::RepairReport>,
    /// The pixel size its vector images (SVG, text) were rendered at, from the texel density
    /// where it landed; absent for a layer of bitmaps.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub raster_px: Option<[u32; 2]>,
    /// Strokes: the path, stamps and charts (the fields above then add up the stamps: the
    /// placement and frame are the first stamp's; `triangles_covered` counts a triangle once per
    /// stamp; `texels_covered` counts the texels the whole stroke changed).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stroke: Option<StrokeReport>,
}

/// Time per stage, milliseconds.
#[derive(Debug, Clone, Default, Serialize)]
pub struct Timings {
    /// Reading and parsing the mesh.
    pub load_ms: f64,
    /// Welding and adjacency.
    pub weld_ms: f64,
    /// Uploading the mesh.
    pub upload_ms: f64,
    /// Decoding images and uploading them (vector images: rendering them), and sizing the
    /// vector images (`vector_maps_ms`).
    pub images_ms: f64,
    /// Mapping the vector layers' units on the CPU to size their images, included in
    /// `images_ms` (0 without vector layers, and for units the mesh has mapped before).
    pub vector_maps_ms: f64,
    /// Placement on the GPU.
    pub placement_ms: f64,
    /// Conformal charts (selection, refinement, GPU solves), included in `compose_ms`.
    pub charts_ms: f64,
    /// Base, island mask, layer coordinates, selection, raster and compose.
    pub compose_ms: f64,
    /// Padding (distance transform and fill).
    pub padding_ms: f64,
    /// sRGB encode on the GPU and read-back.
    pub encode_ms: f64,
    /// PNG/GLB/preview writing.
    pub write_ms: f64,
    /// The engine's start: instance, adapter, device and the pipeline cache's file (the first
    /// bake of an engine only; 0 in later ones and on a host's device).
    pub startup_ms: f64,
    /// Building pipelines, summed over the threads that built them: those this bake used for the
    /// first time, and for an engine's first bake those built before it (`Engine::prepare_for`,
    /// overlapped with the mesh's load). Already counted in the stages that waited for them.
    pub pipelines_ms: f64,
}

/// Where the stages that have a CPU twin ran: `"gpu"` or `"cpu"` (the twin, taken by default
/// where it is the faster on the adapter in use; `Engine::stage_paths` forces either).
#[derive(Debug, Clone, Serialize)]
pub struct Paths {
    /// Placement: the BVH walk of `place_bvh` on the GPU, or `place::place_cpu_bvh`.
    pub placement: &'static str,
    /// Exponential maps: `expmap_relax` on the GPU, or the CPU twin (`maps::expmap::cpu`);
    /// `"none"` when the bake has none.
    pub expmap: &'static str,
    /// Conformal charts: the batched GPU CG, or the CPU twin's (`solve::cg::pcg`); `"none"`
    /// when the bake has none.
    pub charts: &'static str,
    /// PBR channel groups: `"fused"` (drawn and composed beside the colour in one pass),
    /// `"separate"` (a pass each after the colour's) or `"none"` (the bake paints none).
    pub channels: &'static str,
    /// The layer raster's samples: `"full"` (once a sample) or `"adaptive"` (four samples a
    /// pixel, once a texel and triangle: `texture.sampling`, where the device holds them).
    pub sampling: &'static str,
    /// The islands' distance transform (the padding's nearest island texel): `edt_columns` and
    /// `edt_rows` on the GPU, or the CPU twin (`cpu::nearest_island_map`) over the island mask,
    /// when the islands were computed (a mesh keeps them for later bakes of the same size, which
    /// say the same); `"none"` for a tiled bake (its tiles are padded on the CPU,
    /// `bake::bands`).
    pub islands: &'static str,
    /// Padding and encoding: the `encode` kernel on the GPU, or the canvas read back and padded
    /// on the CPU (an 8-bit texture baked whole on a CPU adapter, `StagePaths::padding`): the
    /// same bytes either way.
    pub padding: &'static str,
}

impl Default for Paths {
    fn default() -> Self {
        Self {
            placement: "gpu",
            expmap: "none",
            charts: "none",
            channels: "none",
            sampling: "full",
            islands: "none",
            padding: "gpu",
        }
    }
}

/// The whole report.
#[derive(Debug, Clone, Serialize)]
pub struct Report {
    /// decalbake version.
    pub version: &'static str,
    /// The adapter used.
    pub adapter: String,
    /// Job file.
    pub job: String,
    /// Mesh statistics.
    pub mesh: MeshStats,
    /// UV set baked into.
    pub uv_set: u32,
    /// Texture size.
    pub texture: [u32; 2],
    /// Samples per texel.
    pub samples: u32,
    /// Padding in texels (`null` = full).
    pub padding: Option<u32>,
    /// Per-layer results.
    pub layers: Vec<LayerReport>,
    /// Island texels (covered by some triangle).
    pub island_texels: u64,
    /// Warnings (e.g. overlapping UVs under a decal, fallback up direction).
    pub warnings: Vec<String>,
    /// Time per stage.
    pub timings: Timings,
    /// GPU dispatches and draws issued.
    pub gpu_commands: u32,
    /// Where the stages that have a CPU twin ran.
    pub paths: Paths,
    /// The compiled pipelines kept on disk (`gpu::cache`): `"warm"` (read from the file),
    /// `"cold"` (no file yet; written after the bake), `"corrupt"` (ignored and replaced),
    /// `"unsupported"` (the backend keeps none) or `"off"`.
    pub pipeline_cache: &'static str,
    /// `decalbake batch`: SHA-256 of the job's inputs (engine version, job text, mesh and image
    /// bytes), which `--resume` compares before skipping a job whose outputs exist.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub input_hash: Option<String>,
    /// `"uv_set": "auto"` on a mesh without UVs: the pelting that made the set baked into.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub unwrap: Option<crate::pelt::UnwrapReport>,
    /// A tiled bake (`bake/tiles.rs`): [tile width, tiles]. Its stage times add up the tiles'.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tiles: Option<[u32; 2]>,
    /// A tiled bake: the tile's [width, height] (squares for `texture.tile`, bands the texture's
    /// width across when the texture is tiled because it does not fit one storage buffer).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tile_size: Option<[u32; 2]>,
    /// A tiled bake written to its files band by band as it was baked (`output/stream.rs`: the
    /// textures never whole in memory); absent where the textures were held whole.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub streamed: bool,
    /// A bake into several texture sets (`crate::bake::sets`): one entry per set. The report's
    /// layers, timings and island texels are then the first set's, with each layer's
    /// `texels_covered` added up over the sets.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub texture_sets: Vec<SetReport>,
}

/// One texture set of a bake.
#[derive(Debug, Clone, Serialize)]
pub struct SetReport {
    /// Its name (`{set}` in file names).
    pub name: String,
    /// The materials it paints (document indices).
    pub materials: Vec<usize>,
    /// Its primitives (`meshes[i].primitives[j]`).
    pub primitives: Vec<String>,
    /// The texture written, or `null` when no layer touched the set.
    pub texture: Option<String>,
    /// Texels the layers changed in it.
    pub texels_covered: u64,
}

/// What a stroke reports (the layer's `stroke` block).
#[derive(Debug, Clone, serde::Serialize)]
pub struct StrokeReport {
    /// The tool.
    #[serde(flatten)]
    pub tool: crate::io::job::Tool,
    /// Path points given.
    pub path_points: usize,
    /// Length of the path on the surface (model units).
    pub path_length: f32,
    /// The 3D chord lengths added up (the path's length if it cut through the model).
    pub chord_length: f32,
    /// Polyline points of the path on the surface (path points and samples every quarter of the
    /// mean edge length).
    pub path_vertices: usize,
    /// Stamps drawn.
    pub stamps: usize,
    /// Stamp distance at full pressure (model units).
    pub spacing: f32,
    /// Charts solved: one per stamp, or with `continuity` the corner charts (each solved once per
    /// chunk of units and shared by the stamps that blend it).
    pub charts: usize,
    /// Conjugate-gradient iterations of the stamps' conformal charts, all rounds, added up.
    pub cg_iterations: u64,
    /// Whether per-vertex interpolated charts were used.
    pub continuity: bool,
    /// The stroke's opacity cap.
    pub opacity: f32,
}
