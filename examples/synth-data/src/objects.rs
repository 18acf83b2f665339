//! The objects of the synthetic datasets: the paper's three (sizes of YCB's master-chef can,
//! cracker box and bowl), the SYMSOL shapes and a mug, each with its analytic symmetry group,
//! or any mesh file.
use std::path::Path;

use bop_dataset::{FileError, mesh_appearance};
use depth_render::primitives::MugShape;
use depth_render::{Material, MeshRepairs, Primitive, TriangleMesh, load_mesh};
use ipdf_metrics::SymmetryGroup;

/// A built-in object (sizes and symmetries: [`ObjectKind::description`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ObjectKind {
    /// YCB 002 master-chef can: a cylinder 102 mm across, 140 mm tall (axis + flip).
    Can,
    /// YCB 003 cracker box: 60 × 158 × 210 mm (the 4 rotations of a box with distinct edges).
    Box,
    /// YCB 024 bowl: 159 mm across, 53 mm tall (its axis).
    Bowl,
    /// SYMSOL tetrahedron, circumradius 60 mm (12 rotations).
    Tetrahedron,
    /// SYMSOL cube, 80 mm edges (24 rotations).
    Cube,
    /// SYMSOL icosahedron, circumradius 60 mm (60 rotations).
    Icosahedron,
    /// SYMSOL cone, 100 mm across, 100 mm tall (its axis).
    Cone,
    /// SYMSOL cylinder, 80 mm across, 120 mm tall (axis + flip).
    Cylinder,
    /// A mug: a cup 80 mm across, 95 mm tall, walls 4 mm thick, with a handle 8 mm thick
    /// standing 34 mm out (no symmetry; seen with the handle hidden, its turns about the axis
    /// look alike).
    Mug,
}

impl ObjectKind {
    /// Every built-in object.
    pub const ALL: [Self; 9] = [
        Self::Can,
        Self::Box,
        Self::Bowl,
        Self::Tetrahedron,
        Self::Cube,
        Self::Icosahedron,
        Self::Cone,
        Self::Cylinder,
        Self::Mug,
    ];

    /// The name used in files and reports.
    pub fn name(self) -> &'static str {
        match self {
            Self::Can => "can",
            Self::Box => "box",
            Self::Bowl => "bowl",
            Self::Tetrahedron => "tetrahedron",
            Self::Cube => "cube",
            Self::Icosahedron => "icosahedron",
            Self::Cone => "cone",
            Self::Cylinder => "cylinder",
            Self::Mug => "mug",
        }
    }

    /// What the object is, with its size and its symmetries.
    pub fn description(self) -> &'static str {
        match self {
            Self::Can => {
                "YCB 002 master-chef can: a cylinder 102 mm across, 140 mm tall (axis + flip)"
            }
            Self::Box => {
                "YCB 003 cracker box: 60 × 158 × 210 mm (the 4 rotations of a box with distinct edges)"
            }
            Self::Bowl => "YCB 024 bowl: 159 mm across, 53 mm tall (its axis)",
            Self::Tetrahedron => "SYMSOL tetrahedron, circumradius 60 mm (12 rotations)",
            Self::Cube => "SYMSOL cube, 80 mm edges (24 rotations)",
            Self::Icosahedron => "SYMSOL icosahedron, circumradius 60 mm (60 rotations)",
            Self::Cone => "SYMSOL cone, 100 mm across, 100 mm tall (its axis)",
            Self::Cylinder => "SYMSOL cylinder, 80 mm across, 120 mm tall (axis + flip)",
            Self::Mug => {
                "a mug: a cup 80 mm across, 95 mm tall, with a handle 8 mm thick standing 34 mm out \
                 (no symmetry)"
            }
        }
    }

    /// The shape (metres).
    pub fn primitive(self) -> Primitive {
        match self {
            Self::Can => Primitive::Cylinder {
                radius: 0.051,
                height: 0.140,
                segments: 96,
            },
            Self::Box => Primitive::Cuboid {
                extents: [0.060, 0.158, 0.210],
            },
            Self::Bowl => Primitive::Bowl {
                radius: 0.0795,
                height: 0.053,
                thickness: 0.004,
                segments: 96,
                rings: 8,
            },
            Self::Tetrahedron => Primitive::Tetrahedron { circumradius: 0.06 },
            Self::Cube => Primitive::Cuboid { extents: [0.08; 3] },
            Self::Icosahedron => Primitive::Icosahedron { circumradius: 0.06 },
            Self::Cone => Primitive::Cone {
                radius: 0.05,
                height: 0.1,
                segments: 96,
            },
            Self::Cylinder => Primitive::Cylinder {
                radius: 0.04,
                height: 0.12,
                segments: 96,
            },
            Self::Mug => Primitive::Mug(MugShape {
                radius: 0.04,
                height: 0.095,
                wall: 0.004,
                handle_reach: 0.03,
                handle_thickness: 0.008,
                segments: 96,
            }),
        }
    }

    /// The flat colour of the "uniform" variant (linear RGB).
    pub fn colour(self) -> [f32; 3] {
        match self {
            Self::Can => [0.75, 0.2, 0.15],
            Self::Box => [0.85, 0.65, 0.15],
            Self::Bowl => [0.2, 0.45, 0.8],
            Self::Tetrahedron => [0.3, 0.7, 0.3],
            Self::Cube => [0.7, 0.3, 0.7],
            Self::Icosahedron => [0.25, 0.65, 0.7],
            Self::Cone => [0.8, 0.45, 0.3],
            Self::Cylinder => [0.55, 0.55, 0.25],
            Self::Mug => [0.9, 0.9, 0.85],
        }
    }
}

/// An object of a synthetic dataset.
#[derive(Debug, Clone)]
pub struct SynthObject {
    /// Its name in reports (`can`, or the mesh file's stem).
    pub name: String,
    /// The mesh (metres, model frame).
    pub mesh: TriangleMesh,
    /// Its proper symmetries (translations in metres); none for a mesh file.
    pub symmetry: SymmetryGroup,
    /// The flat colour of the "uniform" variant.
    pub colour: [f32; 3],
    /// Its own surface, where its mesh file gives one (the texture image it names, else its
    /// vertex colours): what the "texture" variant shows instead of colour patches.
    pub appearance: Option<Material>,
}

impl SynthObject {
    /// A built-in object.
    pub fn built_in(kind: ObjectKind) -> Result<Self, depth_render::RenderError> {
        let primitive = kind.primitive();
        Ok(Self {
            name: kind.name().to_string(),
            mesh: primitive.mesh()?,
            symmetry: {
                let shape = primitive.symmetry()?;
                SymmetryGroup::about_origin(&shape.discrete, &shape.continuous)
            },
            colour: kind.colour(),
            appearance: None,
        })
    }

    /// An object from a mesh file (`scale`: its unit in metres, 0.001 for BOP's mm), with no
    /// known symmetry, grey in the "uniform" variant and its own texture or vertex colours,
    /// where the file has them, in the "texture" variant; and what loading repaired in the mesh.
    /// A texture image the file names but that cannot be read is refused, naming it.
    pub fn from_mesh_file(path: &Path, scale: f64) -> Result<(Self, MeshRepairs), FileError> {
        let loaded = load_mesh(path, scale).map_err(|e| match e {
            depth_render::RenderError::MeshFile {
                path,
                field,
                reason,
            } => FileError::new(&path, field, reason),
            other => FileError::new(path, "mesh", other.to_string()),
        })?;
        let name = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "mesh".into());
        let appearance = mesh_appearance(path, &loaded)?;
        let object = Self {
            name,
            mesh: loaded.mesh,
            symmetry: SymmetryGroup::none(),
            colour: [0.7, 0.7, 0.7],
            appearance,
        };
        Ok((object, loaded.repairs))
    }
}
