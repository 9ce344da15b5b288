//! The renderer's one error type.

/// What can go wrong when describing cameras and markers, setting up the GPU, rendering or
/// encoding a frame. Nothing in this crate panics on bad input: every refusal is one of these.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// A camera model field is out of range (`field` is the field's name, e.g. `width`).
    #[error("invalid camera: {field} = {value}: {expected}")]
    InvalidCamera {
        /// The field: `width`, `height` or `horizontal_fov_deg`.
        field: &'static str,
        /// The refused value, as given.
        value: String,
        /// What the field accepts.
        expected: &'static str,
    },
    /// A camera view (pose or mount) has a non-finite or degenerate field.
    #[error("invalid camera view: {field}: {expected}")]
    InvalidView {
        /// The field, e.g. `views[3].position_enu_m` or `mount.offset_flu_m`.
        field: String,
        /// What the field accepts.
        expected: &'static str,
    },
    /// A ground marker is malformed (`field` names it, e.g. `markers[0].cells`).
    #[error("invalid marker: {field}: {expected}")]
    InvalidMarker {
        /// The field, e.g. `markers[2].size_m`.
        field: String,
        /// What the field accepts.
        expected: String,
    },
    /// No Vulkan adapter: the machine has neither a GPU driver with Vulkan nor Mesa's
    /// software rasteriser (lavapipe).
    #[error(
        "no Vulkan adapter found ({0}): install a GPU driver with Vulkan support, or Mesa's \
         CPU rasteriser lavapipe (Debian/Ubuntu: apt-get install mesa-vulkan-drivers libvulkan1)"
    )]
    NoAdapter(String),
    /// The adapter was found but refused to open a device with the limits we need.
    #[error("failed to open the Vulkan device on {adapter}: {reason}")]
    Device {
        /// The adapter's name, e.g. `llvmpipe (LLVM 15.0.6, 256 bits)`.
        adapter: String,
        /// wgpu's message.
        reason: String,
    },
    /// The GPU reported an error while rendering or reading back (validation, out of
    /// memory, device lost).
    #[error("failed to render: {0}")]
    Gpu(String),
    /// A frame could not be encoded (PNG or JPEG).
    #[error("failed to encode the frame as {format}: {reason}")]
    Encode {
        /// `PNG` or `JPEG`.
        format: &'static str,
        /// The encoder's message.
        reason: String,
    },
}

/// The crate's result type.
pub type Result<T, E = RenderError> = std::result::Result<T, E>;
