// SPDX-License-Identifier: MIT OR Apache-2.0
//! glTF 2.0 loading (`.gltf` with external or data-URI buffers, and `.glb`).
//!
//! Every triangle primitive of the default scene (or the first scene) is taken with its node's world
//! transform applied. Positions, normals (computed, area-weighted over the welded surface, when a
//! primitive has none), indices (generated when absent), every `TEXCOORD_n` set, `TANGENT` (when
//! every primitive has it) and the base-colour texture of the first textured material are read. The result keeps glTF's split vertices, which
//! rasterization needs; [`crate::mesh::Topology`] welds them for the surface.

use super::checks::{self, gltf_err};
use super::decode;
use super::document::SourceDocument;
use crate::error::{Error, Result};
use crate::io::image::LinearImage;
use glam::{Mat3, Mat4, Vec2, Vec3};
use gltf::accessor::{DataType, Dimensions};
use std::path::{Path, PathBuf};

/// One glTF primitive as it appears in the scene.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct PrimitiveInfo {
    /// `mesh[i].primitives[j]` in the source file.
    pub name: String,
    /// `i` of `meshes[i].primitives[j]`.
    #[serde(skip)]
    pub mesh_index: usize,
    /// `j` of `meshes[i].primitives[j]`.
    #[serde(skip)]
    pub primitive_index: usize,
    /// The node that draws this instance.
    #[serde(skip)]
    pub node: usize,
    /// The primitive's vertex 0 in [`Mesh::positions`] as loaded (its vertices follow in order).
    #[serde(skip)]
    pub first_vertex: u32,
    /// Whether the node's transform mirrors it (its triangles' winding was turned on loading).
    #[serde(skip)]
    pub flipped: bool,
    /// First triangle of this primitive in [`Mesh::triangles`].
    pub first_triangle: u32,
    /// Triangle count.
    pub triangles: u32,
    /// Vertex count (glTF, split).
    pub vertices: u32,
    /// Number of `TEXCOORD_n` sets it has.
    pub uv_sets: u32,
    /// Whether the file supplied normals.
    pub has_normals: bool,
    /// Material index, if any.
    pub material: Option<usize>,
}

/// Material data the baker uses.
#[derive(Debug, Clone)]
pub struct MaterialInfo {
    /// Its index in the document's `materials`.
    pub index: usize,
    /// `baseColorFactor`, linear RGBA.
    pub base_color_factor: [f32; 4],
    /// The base-colour texture decoded to linear RGBA, if the material has one.
    pub base_color_texture: Option<LinearImage>,
    /// Which `TEXCOORD_n` the base-colour texture uses.
    pub base_color_uv_set: u32,
    /// `metallicFactor`.
    pub metallic: f32,
    /// `roughnessFactor`.
    pub roughness: f32,
}

/// A triangle mesh as loaded: split (per-UV-seam) vertices with world-space attributes.
#[derive(Debug, Clone, Default)]
pub struct Mesh {
    /// Where it came from (for error messages).
    pub source: PathBuf,
    /// World-space positions, one per split vertex.
    pub positions: Vec<Vec3>,
    /// World-space unit normals, one per split vertex.
    pub normals: Vec<Vec3>,
    /// World-space tangents `TANGENT`, one per split vertex, when every primitive has them (empty
    /// otherwise): xyz through the node's linear part, normalised (zero where that fails), w the
    /// bitangent sign as in glTF (bitangent = cross(normal, xyz) · w), negated where the node's
    /// transform mirrors. [`crate::mesh::tangents::tangents`] gives a frame per vertex either way.
    pub tangents: Vec<[f32; 4]>,
    /// `uv_sets[n][v]` is `TEXCOORD_n` of split vertex `v`: every set some primitive has. A
    /// primitive without set `n` has (0, 0) at every vertex, so its triangles cover no texel of
    /// that set (`PrimitiveInfo::uv_sets` says which sets it has).
    pub uv_sets: Vec<Vec<Vec2>>,
    /// Triangles as split vertex indices, counter-clockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
    /// The primitives, in scene order.
    pub primitives: Vec<PrimitiveInfo>,
    /// Material of the first primitive that has one (the baked texture replaces its base colour).
    pub material: Option<MaterialInfo>,
    /// The custom attribute `_PELT_BLEND` per split vertex, when every primitive has it: the
    /// pelt's weight of `decalbake unwrap --patch` (`crate::pelt::patch`); empty otherwise.
    pub blend: Vec<f32>,
    /// The custom attribute `_PELT_BRIDGE` per split vertex, when every primitive has it: the
    /// weight of the third set that `decalbake unwrap --patch` writes on models whose seams have
    /// cycles (`crate::pelt::bridge`; the patch's weight is then 1 − blend − bridge); empty
    /// otherwise.
    pub bridge: Vec<f32>,
    /// The glTF document it was loaded from (`None` for a mesh made in code), which the writer
    /// gives back with the bake's changes (`crate::output::gltf`).
    pub document: Option<std::sync::Arc<SourceDocument>>,
    /// Each split vertex's vertex as loaded, where the vertices were split or reordered since
    /// (a new UV set by pelting, `crate::pelt::apply_all`); empty: the vertices are as loaded.
    pub vertex_origin: Vec<u32>,
    /// The UV sets made since loading (by pelting), which the writer adds to the document's
    /// primitives as `TEXCOORD_n` (replacing a set of that number).
    pub new_uv_sets: Vec<usize>,
}

/// The primitive's custom attribute `_{attribute}` (one float per vertex: `_PELT_BLEND`,
/// `_PELT_BRIDGE`), if it has one of the right type and length.
fn read_weight(
    prim: &gltf::Primitive,
    buffers: &[gltf::buffer::Data],
    vertices: usize,
    attribute: &str,
    name: &Path,
) -> Option<Vec<f32>> {
    let accessor = prim.get(&gltf::Semantic::Extras(attribute.into()))?;
    let scalar = [(DataType::F32, Dimensions::Scalar)];
    checks::accessor(&accessor, &format!("_{attribute}"), &scalar, false, name)
        .ok()
        .filter(|&n| n == vertices)?;
    let it = gltf::accessor::Iter::<f32>::new(accessor, |b: gltf::Buffer| {
        buffers.get(b.index()).map(|d| &d.0[..])
    })?;
    Some(it.collect::<Vec<f32>>()).filter(|v| v.len() == vertices)
}

/// The primitive's `TANGENT` in world space (`m3`: the node's linear part; `flip`: it mirrors), if
/// it has one of the right type and length; a malformed one is skipped with a warning (the
/// tangents are then generated, [`crate::mesh::tangents::tangents`]).
fn read_tangents(
    prim: &gltf::Primitive,
    buffers: &[gltf::buffer::Data],
    (vertices, m3, flip): (usize, Mat3, bool),
    pname: &str,
    name: &Path,
) -> Option<Vec<[f32; 4]>> {
    let accessor = prim.get(&gltf::Semantic::Tangents)?;
    let what = format!("{pname} TANGENT");
    let types = [(DataType::F32, Dimensions::Vec4)];
    match checks::accessor(&accessor, &what, &types, false, name) {
        Ok(n) if n == vertices => {}
        Ok(n) => {
            log::warn!("{}: {what} has {n} elements for {vertices} vertices; ignored (tangents are generated)", name.display());
            return None;
        }
        Err(e) => {
            log::warn!("{e}; {what} ignored (tangents are generated)");
            return None;
        }
    }
    let reader = prim.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
    let sign = if flip { -1.0 } else { 1.0 };
    let out: Vec<[f32; 4]> = reader
        .read_tangents()?
        .map(|[x, y, z, w]| {
            let t = (m3 * Vec3::new(x, y, z)).normalize_or_zero();
            [t.x, t.y, t.z, w * sign]
        })
        .collect();
    Some(out).filter(|t| t.len() == vertices)
}

/// What the scene's primitives hold beyond positions, normals and triangles, joined at the end
/// ([`Mesh::join_primitive_attributes`]).
#[derive(Default)]
struct PerPrimitive {
    uvs: Vec<Vec<Vec<Vec2>>>,
    blend: Vec<Option<Vec<f32>>>,
    bridge: Vec<Option<Vec<f32>>>,
    tangents: Vec<Option<Vec<[f32; 4]>>>,
    material: Option<usize>,
}

impl Mesh {
    /// Loads a `.gltf` or `.glb` file.
    pub fn load(path: &Path) -> Result<Self> {
        let bytes = std::fs::read(path).map_err(|source| Error::Io {
            path: path.to_path_buf(),
            action: "reading the mesh",
            source,
        })?;
        Self::from_bytes(&bytes, path, path.parent())
    }

    /// Loads glTF from memory. `name` is used in messages; `base` resolves external URIs (`None`
    /// allows only embedded data).
    pub fn from_bytes(bytes: &[u8], name: &Path, base: Option<&Path>) -> Result<Self> {
        let gltf = checks::parse(bytes, name)?;
        let base_dir = base.map(|b| {
            if b.as_os_str().is_empty() {
                Path::new(".")
            } else {
                b
            }
        });
        checks::uris(&gltf.document, base_dir, name)?;
        // Compressed geometry decoded first: the crate reads the uncompressed document.
        let (document, buffers, json) = match decode::decode(&gltf, bytes, name, base_dir)? {
            Some(d) => (d.document, d.buffers, d.json),
            None => {
                let buffers = gltf::import_buffers(&gltf.document, base_dir, gltf.blob)
                    .map_err(|e| gltf_err(name, format!("loading buffers: {e}")))?;
                (gltf.document, buffers, checks::raw_json(bytes, name)?)
            }
        };
        checks::views(&document, &buffers, name)?;

        let scene = document
            .default_scene()
            .or_else(|| document.scenes().next())
            .ok_or_else(|| Error::mesh(name, "the file has no scene, so no triangles to bake onto; export the model with a scene"))?;

        let mut mesh = Mesh {
            source: name.to_path_buf(),
            ..Default::default()
        };
        let mut per = PerPrimitive::default();
        let mut stack: Vec<(gltf::Node, Mat4)> =
            scene.nodes().map(|n| (n, Mat4::IDENTITY)).collect();
        let mut seen = vec![false; document.nodes().len()];
        while let Some((node, parent)) = stack.pop() {
            if std::mem::replace(&mut seen[node.index()], true) {
                return Err(gltf_err(name, format!("nodes[{}] is reached twice from scenes[{}]; a glTF node hierarchy is a tree (one parent per node, no cycles)", node.index(), scene.index())));
            }
            let local = Mat4::from_cols_array_2d(&node.transform().matrix());
            let world = parent * local;
            for child in node.children() {
                stack.push((child, world));
            }
            let Some(gmesh) = node.mesh() else { continue };
            for prim in gmesh.primitives() {
                let pname = format!("meshes[{}].primitives[{}]", gmesh.index(), prim.index());
                if prim.mode() != gltf::mesh::Mode::Triangles {
                    log::warn!(
                        "{}: {pname} is {:?}, not triangles; skipped",
                        name.display(),
                        prim.mode()
                    );
                    continue;
                }
                let at = (node.index(), gmesh.index());
                mesh.add_primitive(&prim, pname, at, world, &buffers, &mut per)?;
            }
        }
        if mesh.triangles.is_empty() {
            return Err(Error::mesh(name, "the scene has no triangles (no triangle primitives in any node); decalbake needs a triangle mesh"));
        }
        if per.tangents.iter().all(Option::is_some) {
            mesh.tangents = per.tangents.into_iter().flatten().flatten().collect();
        }
        mesh.join_primitive_attributes(per.uvs, per.blend, per.bridge);
        let doc = std::sync::Arc::new(SourceDocument {
            json,
            buffers: buffers.into_iter().map(|d| d.0).collect(),
            path: name.to_path_buf(),
            base: base_dir.map(Path::to_path_buf),
        });
        if let Some(mi) = per.material {
            mesh.material = Some(material_info(&doc, mi)?);
        }
        mesh.document = Some(doc);
        Ok(mesh)
    }

    /// Appends primitive `prim` (`pname` in messages) of `(node, mesh)` with the node's `world`
    /// transform; its UV
    /// sets, blend weights and material go to `per`. Every accessor is checked
    /// ([`checks::accessor`]) before the `gltf` crate reads it.
    fn add_primitive(
        &mut self,
        prim: &gltf::Primitive,
        pname: String,
        (node, mesh_index): (usize, usize),
        world: Mat4,
        buffers: &[gltf::buffer::Data],
        per: &mut PerPrimitive,
    ) -> Result<()> {
        use DataType::{F32, U16, U32, U8};
        use Dimensions::{Scalar, Vec2 as V2, Vec3 as V3};
        let name = self.source.clone();
        let name = name.as_path();
        let Some(pos_accessor) = prim.get(&gltf::Semantic::Positions) else {
            return Err(Error::mesh(
                name,
                format!("{pname} has no POSITION attribute; re-export the mesh with positions"),
            ));
        };
        let what = |attr: &str| format!("{pname} {attr}");
        let nverts = checks::accessor(&pos_accessor, &what("POSITION"), &[(F32, V3)], true, name)?;
        let same_count = |attr: &str, a: &gltf::Accessor, types: &[(DataType, Dimensions)]| {
            let n = checks::accessor(a, &what(attr), types, false, name)?;
            if n != nverts {
                return Err(gltf_err(name, format!("{pname} has {nverts} POSITION elements but {n} {attr} elements; each attribute needs one per vertex")));
            }
            Ok(())
        };
        if let Some(a) = prim.get(&gltf::Semantic::Normals) {
            same_count("NORMAL", &a, &[(F32, V3)])?;
        }
        let mut set = 0;
        while let Some(a) = prim.get(&gltf::Semantic::TexCoords(set)) {
            same_count(
                &format!("TEXCOORD_{set}"),
                &a,
                &[(F32, V2), (U8, V2), (U16, V2)],
            )?;
            set += 1;
        }
        let index_types = [(U8, Scalar), (U16, Scalar), (U32, Scalar)];
        let nindices = match prim.indices() {
            Some(a) => checks::accessor(&a, &what("indices"), &index_types, true, name)?,
            None => nverts,
        };
        if self.positions.len() + nverts > checks::MAX_ELEMENTS
            || self.triangles.len() + nindices / 3 > checks::MAX_ELEMENTS
        {
            return Err(Error::mesh(name, format!("the scene has more than {} vertices or triangles (each instance of a mesh counts); decalbake loads at most that many", checks::MAX_ELEMENTS)));
        }
        let reader = prim.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
        let Some(pos_iter) = reader.read_positions() else {
            return Err(Error::mesh(
                name,
                format!("{pname} has no POSITION attribute; re-export the mesh with positions"),
            ));
        };
        let positions: Vec<Vec3> = pos_iter.map(Vec3::from).collect();
        let nverts = positions.len() as u32;
        for (i, p) in positions.iter().enumerate() {
            if !p.is_finite() {
                return Err(Error::mesh(name, format!("{pname} POSITION[{i}] is {p} (not finite); fix or remove that vertex in your modelling tool")));
            }
        }
        let indices: Vec<u32> = match reader.read_indices() {
            Some(ix) => ix.into_u32().collect(),
            None => (0..nverts).collect(),
        };
        if !indices.len().is_multiple_of(3) {
            return Err(Error::mesh(
                name,
                format!("{pname} has {} indices, not a multiple of 3", indices.len()),
            ));
        }
        if let Some((k, &bad)) = indices.iter().enumerate().find(|(_, &i)| i >= nverts) {
            return Err(Error::mesh(name, format!("{pname} indices[{k}] = {bad} is out of range (the primitive has {nverts} vertices); the file is corrupt, re-export it")));
        }
        let normals: Option<Vec<Vec3>> = reader.read_normals().map(|n| n.map(Vec3::from).collect());
        let mut sets = Vec::new();
        let mut set = 0;
        while let Some(tc) = reader.read_tex_coords(set) {
            let uv: Vec<Vec2> = tc.into_f32().map(Vec2::from).collect();
            if let Some((i, u)) = uv.iter().enumerate().find(|(_, u)| !u.is_finite()) {
                return Err(Error::mesh(
                    name,
                    format!("{pname} TEXCOORD_{set}[{i}] is {u} (not finite)"),
                ));
            }
            sets.push(uv);
            set += 1;
        }
        let n = positions.len();
        per.blend
            .push(read_weight(prim, buffers, n, "PELT_BLEND", name));
        per.bridge
            .push(read_weight(prim, buffers, n, "PELT_BRIDGE", name));
        let m3 = Mat3::from_mat4(world);
        let nmat = m3.inverse().transpose();
        let flip = m3.determinant() < 0.0;
        let at = (n, m3, flip);
        per.tangents
            .push(read_tangents(prim, buffers, at, &pname, name));
        let base = self.positions.len() as u32;
        let first_triangle = self.triangles.len() as u32;
        for (i, p) in positions.iter().enumerate() {
            let w = world.transform_point3(*p);
            if !w.is_finite() {
                return Err(Error::mesh(name, format!("{pname} POSITION[{i}] is {w} after its node transforms (not finite); check the nodes' matrix, scale and translation")));
            }
            self.positions.push(w);
        }
        let has_normals = normals.is_some();
        match normals {
            Some(n) => self
                .normals
                .extend(n.iter().map(|n| (nmat * *n).normalize_or_zero())),
            None => self
                .normals
                .extend(std::iter::repeat_n(Vec3::ZERO, positions.len())),
        }
        for t in indices.chunks_exact(3) {
            let tri = [base + t[0], base + t[1], base + t[2]];
            self.triangles
                .push(if flip { [tri[0], tri[2], tri[1]] } else { tri });
        }
        let material = prim.material().index();
        if per.material.is_none() && material.is_some() {
            per.material = material;
        }
        self.primitives.push(PrimitiveInfo {
            name: pname,
            mesh_index,
            primitive_index: prim.index(),
            node,
            first_vertex: base,
            flipped: flip,
            first_triangle,
            triangles: (indices.len() / 3) as u32,
            vertices: nverts,
            uv_sets: sets.len() as u32,
            has_normals,
            material,
        });
        per.uvs.push(sets);
        Ok(())
    }

    /// The per-primitive UV sets, `_PELT_BLEND` and `_PELT_BRIDGE` joined over the whole mesh:
    /// every set some primitive has (a primitive without it at (0, 0), covering no texel), and a
    /// weight only when every primitive has it.
    fn join_primitive_attributes(
        &mut self,
        per_prim_uvs: Vec<Vec<Vec<Vec2>>>,
        per_blend: Vec<Option<Vec<f32>>>,
        per_bridge: Vec<Option<Vec<f32>>>,
    ) {
        let most = per_prim_uvs.iter().map(|s| s.len()).max().unwrap_or(0);
        for n in 0..most {
            let mut set = Vec::with_capacity(self.positions.len());
            for (p, sets) in self.primitives.iter().zip(&per_prim_uvs) {
                match sets.get(n) {
                    Some(uv) => set.extend_from_slice(uv),
                    None => set.extend(std::iter::repeat_n(Vec2::ZERO, p.vertices as usize)),
                }
            }
            self.uv_sets.push(set);
        }
        if per_blend.iter().all(Option::is_some) {
            self.blend = per_blend.into_iter().flatten().flatten().collect();
        }
        if per_bridge.iter().all(Option::is_some) {
            self.bridge = per_bridge.into_iter().flatten().flatten().collect();
        }
    }

    /// Bounding box (min, max) of the positions.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        self.positions.iter().fold(
            (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
            |(lo, hi), p| (lo.min(*p), hi.max(*p)),
        )
    }
}

/// Material `index` of `doc` as the baker uses it: its factors and its base-colour texture
/// decoded (sRGB to linear, with `LinearImage::decode`'s limits), resampled through its
/// `KHR_texture_transform` where it has one.
pub(crate) fn material_info(doc: &SourceDocument, index: usize) -> Result<MaterialInfo> {
    let name = doc.path.as_path();
    let mat = doc
        .array("materials")
        .get(index)
        .ok_or_else(|| gltf_err(name, format!("material {index} does not exist")))?;
    let pbr = &mat["pbrMetallicRoughness"];
    let number = |v: &serde_json::Value, default: f32| v.as_f64().map_or(default, |x| x as f32);
    let mut factor = [1.0f32; 4];
    if let Some(f) = pbr["baseColorFactor"].as_array() {
        for (k, v) in f.iter().take(4).enumerate() {
            factor[k] = number(v, 1.0);
        }
    }
    let mut info = MaterialInfo {
        index,
        base_color_factor: factor,
        base_color_texture: None,
        base_color_uv_set: 0,
        metallic: number(&pbr["metallicFactor"], 1.0),
        roughness: number(&pbr["roughnessFactor"], 1.0),
    };
    let tex = &pbr["baseColorTexture"];
    let Some(t) = tex["index"].as_u64() else {
        return Ok(info);
    };
    info.base_color_uv_set = tex["texCoord"].as_u64().unwrap_or(0) as u32;
    let Some(image) = doc
        .array("textures")
        .get(t as usize)
        .and_then(|t| t["source"].as_u64())
    else {
        return Err(gltf_err(name, format!("materials[{index}].pbrMetallicRoughness.baseColorTexture names textures[{t}], which does not exist or has no source")));
    };
    let what = format!("materials[{index}] baseColorTexture (images[{image}])");
    let image_err = |d: String| Error::Image {
        path: name.to_path_buf(),
        action: "decoding",
        detail: format!("{what}: {d}"),
    };
    let data = doc.image(image as usize).map_err(image_err)?;
    info.base_color_texture = Some(LinearImage::decode(&data.bytes).map_err(image_err)?);
    if let Some(t) = texture_transform(tex) {
        apply_texture_transform(&mut info, t);
    }
    Ok(info)
}

/// A texture reference's `KHR_texture_transform` (the raw JSON of the reference): the affine map
/// from UV to texture coordinates (offset · rotation · scale, as the extension defines it) and
/// its `texCoord` override.
pub(crate) fn texture_transform(info: &serde_json::Value) -> Option<(glam::Affine2, Option<u32>)> {
    let t = info.pointer("/extensions/KHR_texture_transform")?;
    let pair = |key: &str, default: Vec2| {
        t.get(key)
            .and_then(|v| v.as_array())
            .and_then(|a| {
                Some(Vec2::new(
                    a.first()?.as_f64()? as f32,
                    a.get(1)?.as_f64()? as f32,
                ))
            })
            .unwrap_or(default)
    };
    let (offset, scale) = (pair("offset", Vec2::ZERO), pair("scale", Vec2::ONE));
    let r = t.get("rotation").and_then(|v| v.as_f64()).unwrap_or(0.0) as f32;
    let (s, c) = r.sin_cos();
    // Rows (c, s) and (-s, c), times the scale.
    let linear = glam::Mat2::from_cols(Vec2::new(c, -s) * scale.x, Vec2::new(s, c) * scale.y);
    let set = t.get("texCoord").and_then(|v| v.as_u64()).map(|n| n as u32);
    Some((glam::Affine2::from_mat2_translation(linear, offset), set))
}

/// The material's base-colour texture resampled through its `KHR_texture_transform`, so that the
/// bake's base is what a viewer shows (wrapping as glTF's default sampler); the writer gives the
/// baked texture to the material without the transform.
fn apply_texture_transform(mat: &mut MaterialInfo, (m, set): (glam::Affine2, Option<u32>)) {
    if let Some(set) = set {
        mat.base_color_uv_set = set;
    }
    let Some(img) = &mat.base_color_texture else {
        return;
    };
    mat.base_color_texture = Some(transformed(img, m));
}

/// `img` as laid out on its UV set under texture transform `m` (texture coordinates = m · uv):
/// resampled at each texel's UV, wrapping as glTF's default sampler does.
pub(crate) fn transformed(img: &LinearImage, m: glam::Affine2) -> LinearImage {
    let (w, h) = (img.width, img.height);
    let pixels = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| {
            let uv = Vec2::new((x as f32 + 0.5) / w as f32, (y as f32 + 0.5) / h as f32);
            let t = m.transform_point2(uv);
            img.bilinear(t.x, t.y, true)
        })
        .collect();
    LinearImage {
        width: w,
        height: h,
        pixels,
    }
}

impl Mesh {
    /// Midpoint subdivision: every triangle becomes four; positions, normals, tangents (w: the
    /// first end's) and every UV set are interpolated at edge midpoints (no smoothing, so the surface is unchanged). Seams stay seams:
    /// midpoints are shared per split-vertex edge, and welding joins the two sides again. Used to make
    /// large benchmark meshes from the bundled ones.
    pub fn subdivide(&self) -> Mesh {
        use std::collections::HashMap;
        let mut out = self.clone();
        // New vertices that no document has: the copy is a mesh of its own.
        (out.document, out.vertex_origin, out.new_uv_sets) = (None, Vec::new(), Vec::new());
        let mut mids: HashMap<(u32, u32), u32> = HashMap::new();
        let mut tris = Vec::with_capacity(self.triangles.len() * 4);
        for t in &self.triangles {
            let mut m = [0u32; 3];
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                let key = (a.min(b), a.max(b));
                m[k] = *mids.entry(key).or_insert_with(|| {
                    let (a, b) = (a as usize, b as usize);
                    out.positions
                        .push(0.5 * (self.positions[a] + self.positions[b]));
                    out.normals
                        .push((self.normals[a] + self.normals[b]).normalize_or_zero());
                    if !self.tangents.is_empty() {
                        let (ta, tb) = (self.tangents[a], self.tangents[b]);
                        let t = (Vec3::from_slice(&ta) + Vec3::from_slice(&tb)).normalize_or_zero();
                        out.tangents.push([t.x, t.y, t.z, ta[3]]);
                    }
                    for (set, src) in out.uv_sets.iter_mut().zip(&self.uv_sets) {
                        set.push(0.5 * (src[a] + src[b]));
                    }
                    if !self.blend.is_empty() {
                        out.blend.push(0.5 * (self.blend[a] + self.blend[b]));
                    }
                    if !self.bridge.is_empty() {
                        out.bridge.push(0.5 * (self.bridge[a] + self.bridge[b]));
                    }
                    (out.positions.len() - 1) as u32
                });
            }
            tris.push([t[0], m[0], m[2]]);
            tris.push([m[0], t[1], m[1]]);
            tris.push([m[2], m[1], t[2]]);
            tris.push([m[0], m[1], m[2]]);
        }
        out.triangles = tris;
        let mut first = 0;
        for p in &mut out.primitives {
            p.first_triangle = first;
            p.triangles *= 4;
            first += p.triangles;
        }
        out
    }
}
