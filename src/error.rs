// SPDX-License-Identifier: MIT OR Apache-2.0
//! The library's typed errors.
//!
//! Every variant says *what* went wrong, *where* (file, field, layer) and, where there is one, *what to
//! do*. The binary maps [`Error::is_input_error`] to exit code 2.

use std::path::PathBuf;

/// Everything that can go wrong in decalbake.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// No GPU adapter could be found for the requested backends.
    #[error("no GPU adapter found for backends {backends}: {detail}. On Debian/Ubuntu install the software Vulkan driver with `apt-get install -y mesa-vulkan-drivers`, or try `--backend gl`")]
    NoAdapter {
        /// The backends that were searched.
        backends: String,
        /// What wgpu said.
        detail: String,
    },
    /// The adapter refused to create a device.
    #[error("could not create a GPU device on {adapter}: {detail}")]
    DeviceCreation {
        /// Adapter name.
        adapter: String,
        /// What wgpu said.
        detail: String,
    },
    /// wgpu reported a validation or out-of-memory error inside a GPU operation.
    #[error("GPU error during {stage}: {detail}")]
    Gpu {
        /// The engine stage that issued the work.
        stage: String,
        /// What wgpu said.
        detail: String,
    },
    /// The device was lost (driver reset, destroyed by the host, ...).
    #[error("the GPU device was lost during {stage}: {detail}")]
    DeviceLost {
        /// The engine stage that noticed.
        stage: String,
        /// What wgpu said.
        detail: String,
    },
    /// The job needs a GPU buffer larger than this device allows (its `max_buffer_size` or
    /// `max_storage_buffer_binding_size`): a texture, mesh or layer too large for the device.
    #[error("{what} needs {} in one GPU buffer, above this device's {limit_name} of {}; {hint}", bytes_text(*needed), bytes_text(*limit))]
    DeviceLimit {
        /// What needed the buffer (names the file where there is one).
        what: String,
        /// Bytes needed.
        needed: u64,
        /// The device's limit in bytes.
        limit: u64,
        /// wgpu's name of the limit.
        limit_name: &'static str,
        /// What to do.
        hint: String,
    },
    /// A file could not be read or written.
    #[error("{}: {action} failed: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// "reading", "writing", ...
        action: &'static str,
        /// The OS error.
        source: std::io::Error,
    },
    /// A glTF file is malformed or unsupported.
    #[error("{}: {detail}", path.display())]
    Gltf {
        /// The file.
        path: PathBuf,
        /// What is wrong and what to do.
        detail: String,
    },
    /// A mesh is unusable (no triangles, NaN positions, out-of-range indices, missing UV set...).
    #[error("{}: {detail}", path.display())]
    Mesh {
        /// The file the mesh came from.
        path: PathBuf,
        /// What is wrong and what to do.
        detail: String,
    },
    /// A job file is malformed or has an invalid value.
    #[error("{}: field `{field}`: {detail}", path.display())]
    Job {
        /// The job file.
        path: PathBuf,
        /// JSON path of the offending field, e.g. `layers[2].size`.
        field: String,
        /// What is wrong and what to do.
        detail: String,
    },
    /// An image failed to decode or encode.
    #[error("{}: image {action} failed: {detail}", path.display())]
    Image {
        /// The image file.
        path: PathBuf,
        /// "decoding" or "encoding".
        action: &'static str,
        /// What the decoder said.
        detail: String,
    },
    /// A layer could not be placed on the mesh.
    #[error("{}: layer {layer} (`layers[{layer}]`): {detail}", path.display())]
    Placement {
        /// The job file.
        path: PathBuf,
        /// Index of the layer in the job.
        layer: usize,
        /// What is wrong and what to do.
        detail: String,
    },
}

impl Error {
    /// True for errors caused by the user's input (files, job values, and a job or mesh too large
    /// for the device: the fix is in the job), false for environment and GPU failures. The CLI exits with code 2 for input errors and 1 for the rest.
    pub fn is_input_error(&self) -> bool {
        matches!(
            self,
            Error::Io { .. }
                | Error::DeviceLimit { .. }
                | Error::Gltf { .. }
                | Error::Mesh { .. }
                | Error::Job { .. }
                | Error::Image { .. }
                | Error::Placement { .. }
        )
    }

    pub(crate) fn job(
        path: &std::path::Path,
        field: impl Into<String>,
        detail: impl Into<String>,
    ) -> Self {
        Error::Job {
            path: path.to_path_buf(),
            field: field.into(),
            detail: detail.into(),
        }
    }

    pub(crate) fn mesh(path: &std::path::Path, detail: impl Into<String>) -> Self {
        Error::Mesh {
            path: path.to_path_buf(),
            detail: detail.into(),
        }
    }
}

/// A byte count as people read it: `512 KiB`, `1.5 MiB`, `2.0 GiB`.
pub fn bytes_text(b: u64) -> String {
    match b {
        0..1024 => format!("{b} bytes"),
        1024..1_048_576 => format!("{:.0} KiB", b as f64 / 1024.0),
        1_048_576..1_073_741_824 => format!("{:.1} MiB", b as f64 / 1_048_576.0),
        _ => format!("{:.1} GiB", b as f64 / 1_073_741_824.0),
    }
}

/// Shorthand for `Result<T, decalbake::Error>`.
pub type Result<T> = std::result::Result<T, Error>;
