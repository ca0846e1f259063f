// SPDX-License-Identifier: MIT OR Apache-2.0
//! A new UV set by pelting, from the library: Spot unwrapped by the automatic cut, the layout's
//! quality printed, and the model written back whole with its new `TEXCOORD_1` (what
//! `decalbake unwrap` does).
//!
//! ```text
//! cargo run --example unwrap            # the engine's choice: the CPU twin on a CPU adapter
//! cargo run --example unwrap -- --cpu   # the CPU twin, no GPU device made
//! ```

use decalbake::mesh::{Mesh, Topology, DEFAULT_WELD_TOLERANCE};
use decalbake::pelt::{self, Device, Options};
use decalbake::Engine;
use std::path::Path;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let cpu = std::env::args().any(|a| a == "--cpu");
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/spot.glb");
    let mut mesh = Mesh::load(&path)?;
    let topo = Topology::build(&mesh, DEFAULT_WELD_TOLERANCE);
    topo.fill_normals(&mut mesh);

    let engine = if cpu { None } else { Some(Engine::new(None)?) };
    let device = match &engine {
        Some(e) => e.pelt_device(),
        None => Device::Cpu,
    };
    let opts = Options {
        size: 1024,
        ..Options::default()
    };
    let unwrapped = pelt::unwrap(device, &mesh, &topo, &opts, &path)?;
    let r = &unwrapped.report;
    println!(
        "{} pelts on the {}, {} flipped, {} overlaps, {:.0} % of the texture used, angle distortion mean {:.3}",
        r.pieces.len(),
        r.device,
        r.quality.flipped,
        r.quality.overlaps,
        100.0 * r.quality.texel_utilisation,
        r.quality.angle_distortion.mean
    );

    // The model as it came in, with the layout as its next UV set.
    let set = mesh.uv_sets.len();
    let out_mesh = pelt::apply(&mesh, &unwrapped, set);
    let out = std::env::temp_dir().join(format!("spot-unwrapped-{}.glb", std::process::id()));
    let written = decalbake::output::gltf::write_model(&out_mesh, &[], &out)?;
    decalbake::output::write_files(&written.files)?;
    let back = Mesh::load(&out)?;
    println!(
        "{}: {} UV sets (TEXCOORD_{set} is new)",
        out.display(),
        back.uv_sets.len()
    );
    assert_eq!(back.uv_sets.len(), set + 1);
    std::fs::remove_file(&out)?;
    Ok(())
}
