//! PLY and OBJ loading, including malformed files: every error names the file and the field.
use std::path::{Path, PathBuf};

use depth_render::{RenderError, load_mesh};

const ASCII_PLY: &str = "ply
format ascii 1.0
comment a unit square (as a quad) and a triangle, in millimetres
element vertex 5
property float x
property float y
property float z
property uchar red
property uchar green
property uchar blue
element face 2
property list uchar int vertex_indices
end_header
0 0 0 255 0 0
1000 0 0 255 0 0
1000 1000 0 255 0 0
0 1000 0 255 0 0
0 0 1000 0 0 255
4 0 1 2 3
3 0 4 1
";

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

fn binary_ply(faces: &[&[u32]], truncate: usize) -> Vec<u8> {
    let vertices: [[f32; 3]; 4] = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.5],
    ];
    let mut bytes = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
         property float z\nelement face {}\nproperty list uchar uint vertex_indices\nend_header\n",
        faces.len()
    )
    .into_bytes();
    for v in vertices {
        v.iter().for_each(|c| bytes.extend(c.to_le_bytes()));
    }
    for face in faces {
        bytes.push(face.len() as u8);
        face.iter().for_each(|i| bytes.extend(i.to_le_bytes()));
    }
    bytes.truncate(bytes.len() - truncate);
    bytes
}

/// A binary PLY whose vertex `index` has x = NaN.
fn with_nan_vertex(index: usize) -> Vec<u8> {
    let mut bytes = binary_ply(&[&[0, 1, 2]], 0);
    let body = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .unwrap()
        + 11;
    bytes[body + 12 * index..body + 12 * index + 4].copy_from_slice(&f32::NAN.to_le_bytes());
    bytes
}

#[test]
fn ascii_ply_in_millimetres_is_scaled_and_triangulated() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = load_mesh(
        &write(dir.path(), "obj_000001.ply", ASCII_PLY.as_bytes()),
        0.001,
    )
    .unwrap()
    .mesh;
    assert_eq!(mesh.triangles().len(), 3);
    assert_eq!(mesh.positions()[2].x, 1.0);
    assert!((mesh.surface_area() - 1.5).abs() < 1e-6);
}

#[test]
fn binary_ply_and_obj_load_the_same_geometry() {
    let dir = tempfile::tempdir().unwrap();
    let ply = load_mesh(
        &write(dir.path(), "m.ply", &binary_ply(&[&[0, 1, 2, 3]], 0)),
        1.0,
    )
    .unwrap()
    .mesh;
    let obj_text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0.5\nf 1 2 3 4\n";
    let obj = load_mesh(&write(dir.path(), "m.obj", obj_text.as_bytes()), 1.0)
        .unwrap()
        .mesh;
    assert_eq!(ply.triangles(), obj.triangles());
    assert_eq!(ply.positions(), obj.positions());
    assert_eq!(ply.triangles(), &[[0, 1, 2], [0, 2, 3]]);
}

#[test]
fn malformed_files_name_the_file_and_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let cases: Vec<(PathBuf, &str)> = vec![
        (
            write(dir.path(), "truncated.ply", &binary_ply(&[&[0, 1, 2]], 3)),
            "file",
        ),
        (
            write(
                dir.path(),
                "range.ply",
                &binary_ply(&[&[0, 1, 2], &[0, 2, 7]], 0),
            ),
            "face[1]",
        ),
        // A zero-area face among others is repaired (tests/mesh_repair.rs); a face index out
        // of range is not.
        (
            write(
                dir.path(),
                "range.ply",
                &binary_ply(&[&[0, 1, 2], &[0, 1, 9]], 0),
            ),
            "face[1]",
        ),
        (
            write(dir.path(), "nan.ply", &with_nan_vertex(2)),
            "vertex[2]",
        ),
        (
            write(
                dir.path(),
                "noface.ply",
                ASCII_PLY
                    .replace("element face 2", "element edge 2")
                    .as_bytes(),
            ),
            "face",
        ),
        (
            write(
                dir.path(),
                "noy.ply",
                ASCII_PLY
                    .replace("property float y", "property float w")
                    .as_bytes(),
            ),
            "vertex[0].y",
        ),
        (
            write(dir.path(), "garbage.ply", b"not a ply at all"),
            "file",
        ),
        // tobj rejects out-of-range indices itself ("face vertex index out of bounds").
        (
            write(dir.path(), "bad.obj", b"v 0 0 0\nv 1 0 0\nf 1 2 9\n"),
            "file",
        ),
        (
            write(
                dir.path(),
                "flat.obj",
                b"v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n",
            ),
            "face",
        ),
        (write(dir.path(), "mesh.stl", b"solid"), "extension"),
        (dir.path().join("missing.ply"), "file"),
    ];
    for (path, field) in cases {
        match load_mesh(&path, 1.0) {
            Err(RenderError::MeshFile {
                path: p,
                field: f,
                reason,
            }) => {
                assert_eq!(p, path);
                assert_eq!(f, field, "{}: {reason}", path.display());
            }
            other => panic!(
                "{}: expected an error on {field}, got {other:?}",
                path.display()
            ),
        }
    }
    let ok = write(dir.path(), "ok.ply", ASCII_PLY.as_bytes());
    assert!(
        matches!(load_mesh(&ok, 0.0), Err(RenderError::MeshFile { field, .. }) if field == "scale")
    );
}

#[test]
fn vertex_colours_normals_and_texture_coordinates_are_kept() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = load_mesh(&write(dir.path(), "c.ply", ASCII_PLY.as_bytes()), 0.001)
        .unwrap()
        .mesh;
    let colors = mesh.colors().unwrap();
    assert_eq!(colors[0], [1.0, 0.0, 0.0]);
    assert_eq!(colors[4], [0.0, 0.0, 1.0]);
    assert!(mesh.normals().is_none() && mesh.uvs().is_none());

    let ply = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
               property float z\nproperty float nx\nproperty float ny\nproperty float nz\n\
               property float s\nproperty float t\nelement face 1\n\
               property list uchar int vertex_indices\nend_header\n\
               0 0 0 0 0 2 0 0\n1 0 0 0 0 2 1 0\n0 1 0 0 0 2 0 1\n3 0 1 2\n";
    let mesh = load_mesh(&write(dir.path(), "n.ply", ply.as_bytes()), 1.0)
        .unwrap()
        .mesh;
    assert_eq!(
        mesh.normals().unwrap()[1],
        nalgebra::Vector3::new(0.0, 0.0, 1.0)
    );
    assert_eq!(mesh.uvs().unwrap()[2], [0.0, 1.0]);

    let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nvn 0 0 1\nf 1/1/1 2/2/1 3/3/1\n";
    let mesh = load_mesh(&write(dir.path(), "t.obj", obj.as_bytes()), 1.0)
        .unwrap()
        .mesh;
    assert_eq!(mesh.uvs().unwrap()[1], [1.0, 0.0]);
    assert_eq!(
        mesh.normals().unwrap()[0],
        nalgebra::Vector3::new(0.0, 0.0, 1.0)
    );

    // A zero normal is recomputed from the vertex's triangle, and counted.
    let bad = ply.replace("1 0 0 0 0 2 1 0", "1 0 0 0 0 0 1 0");
    let loaded = load_mesh(&write(dir.path(), "bad.ply", bad.as_bytes()), 1.0).unwrap();
    assert_eq!(loaded.repairs.normals, 1);
    assert_eq!(
        loaded.mesh.normals().unwrap()[1],
        nalgebra::Vector3::new(0.0, 0.0, 1.0)
    );
}

#[test]
fn the_texture_image_a_file_names_is_reported_beside_it() {
    let dir = tempfile::tempdir().unwrap();
    // PLY as MeshLab and BOP's textured models write it: per-vertex texture_u/texture_v and
    // the image named in a header comment.
    let ply = |comment: &str, uv: bool| {
        let (properties, vertices) = if uv {
            let properties = "property float texture_u\nproperty float texture_v\n";
            (properties, "0 0 0 0 0\n1 0 0 1 0\n0 1 0 0 1\n")
        } else {
            ("", "0 0 0\n1 0 0\n0 1 0\n")
        };
        format!(
            "ply\nformat ascii 1.0\n{comment}element vertex 3\nproperty float x\n\
             property float y\nproperty float z\n{properties}element face 1\n\
             property list uchar int vertex_indices\nend_header\n{vertices}3 0 1 2\n"
        )
    };
    let textured = ply("comment TextureFile obj_000001.png\n", true);
    let loaded = load_mesh(&write(dir.path(), "m.ply", textured.as_bytes()), 1.0).unwrap();
    assert_eq!(loaded.texture, Some(dir.path().join("obj_000001.png")));
    assert_eq!(loaded.mesh.uvs().unwrap()[1], [1.0, 0.0]);
    // No image named, or no coordinates to index it: no texture.
    for (name, comment, uv) in [
        ("p.ply", "comment made by hand\n", true),
        ("n.ply", "comment TextureFile t.png\n", false),
    ] {
        let file = write(dir.path(), name, ply(comment, uv).as_bytes());
        assert_eq!(load_mesh(&file, 1.0).unwrap().texture, None, "{name}");
    }

    // OBJ: the material's map_Kd, from the library beside it; a missing library, none.
    let obj = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n\
               usemtl skin\nf 1/1 2/2 3/3\n";
    let path = write(dir.path(), "t.obj", obj.as_bytes());
    assert_eq!(load_mesh(&path, 1.0).unwrap().texture, None);
    write(
        dir.path(),
        "m.mtl",
        b"newmtl skin\nKd 1 1 1\nmap_Kd skin.jpg\n",
    );
    assert_eq!(
        load_mesh(&path, 1.0).unwrap().texture,
        Some(dir.path().join("skin.jpg"))
    );
}

#[test]
fn attributes_of_the_wrong_length_or_range_are_typed_errors() {
    let mesh = depth_render::primitives::tetrahedron(0.1).unwrap();
    let n = mesh.positions().len();
    let error = mesh.clone().with_uvs(vec![[0.0, 0.0]; n - 1]).unwrap_err();
    assert!(
        matches!(
            error,
            RenderError::InvalidAttribute {
                attribute: "uvs",
                ..
            }
        ),
        "{error}"
    );
    let mut colors = vec![[0.5f32; 3]; n];
    colors[2] = [0.5, 1.5, 0.5];
    let error = mesh.clone().with_colors(colors).unwrap_err();
    assert!(
        matches!(
            error,
            RenderError::InvalidAttribute {
                attribute: "colors",
                vertex: 2,
                ..
            }
        ),
        "{error}"
    );
    let mut normals = vec![nalgebra::Vector3::z(); n];
    normals[1].x = f32::NAN;
    let error = mesh.with_normals(normals).unwrap_err();
    assert!(
        matches!(
            error,
            RenderError::InvalidAttribute {
                attribute: "normals",
                vertex: 1,
                ..
            }
        ),
        "{error}"
    );
}

#[test]
fn vertices_round_trip_with_and_without_normals() {
    use depth_render::{Vertices, load_vertices, write_ply};
    use nalgebra::{Point3, Vector3};
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cloud.ply");
    let positions = vec![Point3::new(0.1, -0.2, 0.3), Point3::new(1.0, 2.0, 3.0)];
    let normals = vec![Vector3::x(), Vector3::new(0.0, 0.6, 0.8)];
    for normals in [None, Some(normals)] {
        let mut bytes = Vec::new();
        write_ply(&mut bytes, &positions, normals.as_deref(), &[], 1.0).unwrap();
        std::fs::write(&path, bytes).unwrap();
        let expected = Vertices {
            positions: positions.clone(),
            normals: normals.clone(),
        };
        assert_eq!(load_vertices(&path, 1.0).unwrap(), expected);
        // A point cloud is no mesh: it has no faces.
        assert!(
            load_mesh(&path, 1.0)
                .unwrap_err()
                .to_string()
                .contains("face: missing")
        );
    }
    let millimetres = load_vertices(&path, 1000.0).unwrap();
    assert!((millimetres.positions[1].z - 3000.0).abs() < 1e-3);
}

#[test]
fn a_written_mesh_loads_as_the_same_mesh() {
    use depth_render::{Primitive, write_ply};
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("can.ply");
    let can = Primitive::Cylinder {
        radius: 0.04,
        height: 0.1,
        segments: 24,
    }
    .mesh()
    .unwrap();
    let mut bytes = Vec::new();
    write_ply(
        &mut bytes,
        can.positions(),
        can.normals(),
        can.triangles(),
        1e3,
    )
    .unwrap();
    std::fs::write(&path, bytes).unwrap();
    let loaded = load_mesh(&path, 1e-3).unwrap();
    assert!(loaded.repairs.is_empty(), "{}", loaded.repairs);
    let back = loaded.mesh;
    assert_eq!(back.triangles(), can.triangles());
    for (a, b) in back.positions().iter().zip(can.positions()) {
        assert!((a - b).norm() < 1e-6, "{a} {b}");
    }
}

#[test]
fn malformed_vertex_files_name_the_field() {
    use depth_render::load_vertices;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.ply");
    let header = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
    let mut binary = header.replace("ascii", "binary_little_endian").into_bytes();
    for value in [0f32, 0.0, 0.0, 1.0, f32::NAN, 1.0] {
        binary.extend_from_slice(&value.to_le_bytes());
    }
    std::fs::write(&path, binary).unwrap();
    let message = load_vertices(&path, 1.0).unwrap_err().to_string();
    assert!(message.contains("vertex[1].y"), "{message}");
    std::fs::write(&path, format!("{header}0 0 0\n")).unwrap();
    let message = load_vertices(&path, 1.0).unwrap_err().to_string();
    assert!(
        message.contains("bad.ply") && message.contains("file"),
        "{message}"
    );
    let with_normals = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
        property float z\nproperty float nx\nproperty float ny\nproperty float nz\nend_header\n";
    std::fs::write(&path, format!("{with_normals}0 0 0 0 0 0\n")).unwrap();
    let message = load_vertices(&path, 1.0).unwrap_err().to_string();
    assert!(
        message.contains("vertex[0].nx") && message.contains("zero-length"),
        "{message}"
    );
    let missing = load_vertices(&dir.path().join("none.ply"), 1.0)
        .unwrap_err()
        .to_string();
    assert!(missing.contains("none.ply"), "{missing}");
    std::fs::write(&path, "ply\nformat ascii 1.0\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n").unwrap();
    let message = load_vertices(&path, 1.0).unwrap_err().to_string();
    assert!(message.contains("vertex: missing"), "{message}");
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(24))]

    /// A mesh written with its vertex colours, texture coordinates and texture image's name
    /// loads with the same geometry, the same colours (8-bit levels), the same texture
    /// coordinates and the image named beside the file.
    #[test]
    fn colours_and_texture_coordinates_round_trip(
        levels in proptest::collection::vec(proptest::prelude::any::<[u8; 3]>(), 64),
        uvs in proptest::collection::vec([0.0f32..1.0, 0.0f32..1.0], 64),
        textured in proptest::prelude::any::<bool>(),
    ) {
        use depth_render::{Primitive, write_mesh_ply_to};
        let can = Primitive::Cylinder { radius: 0.05, height: 0.1, segments: 5 }.mesh().unwrap();
        let n = can.positions().len();
        proptest::prop_assume!(n <= levels.len());
        let colours: Vec<[f32; 3]> =
            levels[..n].iter().map(|c| c.map(|l| f32::from(l) / 255.0)).collect();
        let mesh = can
            .with_colors(colours.clone())
            .unwrap()
            .with_uvs(uvs[..n].to_vec())
            .unwrap();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("can.ply");
        let texture = textured.then_some("can.png");
        let mut bytes = Vec::new();
        write_mesh_ply_to(&mut bytes, &mesh, 1e3, texture).unwrap();
        std::fs::write(&path, bytes).unwrap();
        let loaded = load_mesh(&path, 1e-3).unwrap();
        let back = &loaded.mesh;
        proptest::prop_assert_eq!(back.triangles(), mesh.triangles());
        for (a, b) in back.positions().iter().zip(mesh.positions()) {
            proptest::prop_assert!((a - b).norm() < 1e-6);
        }
        proptest::prop_assert_eq!(back.colors().unwrap(), &colours[..]);
        proptest::prop_assert_eq!(back.uvs().unwrap(), &uvs[..n]);
        proptest::prop_assert_eq!(loaded.texture, texture.map(|t| dir.path().join(t)));
    }
}
