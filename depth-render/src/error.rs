use std::path::PathBuf;

/// Errors of the `depth-render` crate.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum RenderError {
    /// A mesh without vertices or triangles.
    #[error("mesh is empty ({vertices} vertices, {triangles} triangles)")]
    EmptyMesh {
        /// Number of vertices.
        vertices: usize,
        /// Number of triangles.
        triangles: usize,
    },
    /// A vertex coordinate that is NaN or infinite.
    #[error("vertex {vertex} is not finite")]
    NonFiniteVertex {
        /// Index of the vertex.
        vertex: usize,
    },
    /// A triangle referring to a vertex that does not exist.
    #[error("triangle {triangle} refers to vertex {index}, but there are {vertices} vertices")]
    IndexOutOfRange {
        /// Index of the triangle.
        triangle: usize,
        /// The offending vertex index.
        index: u32,
        /// Number of vertices.
        vertices: usize,
    },
    /// A triangle of zero area (repeated or collinear vertices).
    #[error("triangle {triangle} has zero area")]
    DegenerateTriangle {
        /// Index of the triangle.
        triangle: usize,
    },
    /// A per-vertex attribute of the wrong length or with an invalid value.
    #[error("mesh {attribute}: vertex {vertex}: {reason}")]
    InvalidAttribute {
        /// `normals`, `colors` or `uvs`.
        attribute: &'static str,
        /// The first offending vertex.
        vertex: usize,
        /// What is wrong.
        reason: String,
    },
    /// A rendering, instances and materials that do not belong together.
    #[error("rendering does not match its instances: {reason}")]
    RenderingMismatch {
        /// What does not match.
        reason: String,
    },
    /// An image a camera model cannot process.
    #[error("invalid image: {reason}")]
    InvalidImage {
        /// What is wrong.
        reason: String,
    },
    /// An image texture with the wrong number of texels or values outside `[0, 1]`.
    #[error("invalid texture: {reason}")]
    InvalidTexture {
        /// What is wrong.
        reason: String,
    },
    /// A shape whose symmetry group is not a list of discrete rotations and axes.
    #[error("the symmetry group of a {shape} is all of SO(3), not a list of rotations and axes")]
    SymmetryNotRepresentable {
        /// The shape.
        shape: &'static str,
    },
    /// A mesh without a stable resting pose (flat or degenerate convex hull).
    #[error("no stable resting pose: {reason}")]
    NoRestingPose {
        /// Why.
        reason: String,
    },
    /// A mesh file that cannot be read, or whose content is invalid.
    #[error("{path}: {field}: {reason}")]
    MeshFile {
        /// The file.
        path: PathBuf,
        /// The element or field at fault, e.g. `vertex[3].x` or `face[7]`.
        field: String,
        /// What is wrong.
        reason: String,
    },
    /// A mesh whose size at the given scale is not an object's (see [`crate::check_mesh_size`]).
    #[error(
        "{}: the mesh is {} across at {setting} {scale}, not the size of an object{}",
        path.display(),
        length(*size_m),
        suggestion.map(|unit| format!(
            "; is it in {}? {setting} {unit} makes it {} across",
            unit_name(unit),
            length(size_m / scale * unit)
        )).unwrap_or_default()
    )]
    MeshScale {
        /// The mesh file.
        path: PathBuf,
        /// Its bounding-box diagonal at `scale` (metres).
        size_m: f64,
        /// The scale it was read with (metres per file unit).
        scale: f64,
        /// The option that sets the scale.
        setting: String,
        /// The common unit (metres per file unit) that gives an object's size, if one does.
        suggestion: Option<f64>,
    },
    /// Camera intrinsics that cannot image anything.
    #[error("invalid camera: {reason}")]
    InvalidCamera {
        /// What is wrong.
        reason: String,
    },
    /// A primitive's dimension that is not a positive finite number.
    #[error("invalid primitive dimension {name} = {value}")]
    InvalidDimension {
        /// Name of the parameter.
        name: &'static str,
        /// Its value.
        value: f64,
    },
    /// An instance refers to a mesh the scene does not have.
    #[error("instance {instance} refers to mesh {mesh}, but the scene has {meshes}")]
    UnknownMesh {
        /// Position of the instance.
        instance: usize,
        /// The mesh index it names.
        mesh: usize,
        /// Number of meshes in the scene.
        meshes: usize,
    },
    /// A pose with a non-finite rotation or translation.
    #[error("pose of instance {instance} is not finite")]
    NonFinitePose {
        /// Position of the instance.
        instance: usize,
    },
    /// More instances than a [`crate::Rendering`] can label.
    #[error("{count} instances, at most 65536 can be rendered together")]
    TooManyInstances {
        /// Number of instances given.
        count: usize,
    },
}

/// A length in metres, in the unit that reads best.
fn length(metres: f64) -> String {
    if metres >= 1.0 {
        format!("{metres:.3} m")
    } else if metres >= 0.001 {
        format!("{:.1} mm", metres * 1e3)
    } else {
        format!("{:.4} mm", metres * 1e3)
    }
}

/// The name of a unit given in metres (1, 0.01 or 0.001).
fn unit_name(unit: f64) -> &'static str {
    if unit >= 1.0 {
        "metres"
    } else if unit >= 0.01 {
        "centimetres"
    } else {
        "millimetres"
    }
}
