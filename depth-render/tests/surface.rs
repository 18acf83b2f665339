//! Per-pixel surface outputs: barycentrics, normals and shaded RGB.
use depth_render::{
    ImageTexture, Instance, Lighting, Material, PinholeCamera, Primitive, RenderError, Scene,
    Window, primitives, unproject,
};
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};

fn camera() -> PinholeCamera {
    PinholeCamera::new(400.0, 410.0, 40.2, 30.6, 80, 60).unwrap()
}

fn pose(roll: f64, pitch: f64, yaw: f64) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(0.005, -0.01, 0.45),
        UnitQuaternion::from_euler_angles(roll, pitch, yaw),
    )
}

#[test]
fn unprojected_depth_lies_on_the_hit_triangle() {
    let camera = camera();
    let mesh = primitives::icosahedron(0.04).unwrap();
    let scene = Scene::new(std::slice::from_ref(&mesh));
    let instances = [Instance::new(0, pose(0.3, -0.2, 1.1))];
    let out = scene
        .render(&camera, &instances, Window::full(&camera))
        .unwrap();
    let weights = scene.barycentrics(&camera, &instances, &out).unwrap();
    let points = unproject(&camera, out.window, &out.depth, None);
    let hits: Vec<usize> = (0..out.depth.len())
        .filter(|&i| out.depth[i] > 0.0)
        .collect();
    assert_eq!(points.len(), hits.len());
    assert!(hits.len() > 300);
    for (point, &i) in points.iter().zip(&hits) {
        let w = weights[i];
        assert!(w.iter().all(|&x| x >= -1e-5) && (w.iter().sum::<f32>() - 1.0).abs() < 1e-5);
        let corners = mesh.corners(out.triangle[i] as usize);
        let on_surface: Vector3<f64> = (0..3)
            .map(|k| {
                (instances[0].camera_from_model * corners[k].cast::<f64>()).coords * f64::from(w[k])
            })
            .sum();
        assert!(
            (on_surface - point.coords.cast::<f64>()).norm() < 1e-5,
            "pixel {i}"
        );
    }
}

#[test]
fn normals_are_the_outward_face_normals_in_the_camera_frame() {
    let camera = camera();
    // Face-on cube: every visible pixel sees the front face, normal −z.
    let scene = Scene::new(&[primitives::cuboid([0.03, 0.03, 0.03]).unwrap()]);
    let instances = [Instance::new(0, Isometry3::translation(0.0, 0.0, 0.5))];
    let out = scene
        .render(&camera, &instances, Window::full(&camera))
        .unwrap();
    let normals = scene.normals(&camera, &instances, &out).unwrap();
    for (n, d) in normals.iter().zip(&out.depth) {
        if *d > 0.0 {
            assert!((Vector3::from(*n) - Vector3::new(0.0, 0.0, -1.0)).norm() < 1e-6);
        } else {
            assert_eq!(*n, [0.0; 3]);
        }
    }
    // A sphere: the normal of the hit facet is within a facet's angle of the radial direction.
    let scene = Scene::new(&[primitives::sphere(0.05, 4).unwrap()]);
    let instances = [Instance::new(0, pose(0.4, 0.1, -0.3))];
    let out = scene
        .render(&camera, &instances, Window::full(&camera))
        .unwrap();
    let normals = scene.normals(&camera, &instances, &out).unwrap();
    let centre = instances[0].camera_from_model * Point3::origin();
    for (i, p) in unproject(&camera, out.window, &out.depth, None)
        .iter()
        .enumerate()
    {
        let hit = out
            .depth
            .iter()
            .enumerate()
            .filter(|(_, d)| **d > 0.0)
            .nth(i)
            .unwrap()
            .0;
        let radial = (p.cast::<f64>() - centre).normalize();
        assert!(Vector3::from(normals[hit]).cast::<f64>().dot(&radial) > 0.995);
    }
}

#[test]
fn lambert_shading_follows_the_light_and_materials() {
    let camera = camera();
    let scene = Scene::new(&[primitives::sphere(0.05, 4).unwrap()]);
    let instances = [Instance::new(0, Isometry3::translation(0.0, 0.0, 1.0))];
    let out = scene
        .render(&camera, &instances, Window::full(&camera))
        .unwrap();
    let lighting = Lighting {
        towards_light: Vector3::new(-1.0, 0.0, -1.0),
        background: [10, 20, 30],
        ..Lighting::default()
    };
    let rgb = scene
        .shade(
            &camera,
            &instances,
            &[Material::Uniform([1.0, 0.5, 0.0])],
            &lighting,
            &out,
        )
        .unwrap();
    let at = |u: u32, v: u32| rgb[(v * camera.width + u) as usize];
    assert_eq!(at(0, 0), [10, 20, 30]);
    // Left side (towards the light at −x) is brighter than the right side.
    let (left, right) = (at(25, 30), at(55, 30));
    assert!(left[0] > right[0] + 50, "{left:?} vs {right:?}");
    // Uniform orange: green is half of red, no blue.
    assert!((f32::from(left[1]) - 0.5 * f32::from(left[0])).abs() <= 1.0 && left[2] == 0);
    // Ambient light keeps the far side visible.
    assert!(right[0] >= (0.3 * 255.0f32).floor() as u8);
}

#[test]
fn vertex_colours_and_image_textures_are_interpolated() {
    let camera = camera();
    let mesh = primitives::cuboid([0.05, 0.05, 0.05]).unwrap();
    let n = mesh.positions().len();
    let red = mesh.clone().with_colors(vec![[1.0, 0.0, 0.0]; n]).unwrap();
    let uvs: Vec<[f32; 2]> = vec![[0.25, 0.75]; n];
    let textured = mesh.clone().with_uvs(uvs).unwrap();
    // A 2×2 texture: top-left texel (u < 0.5, v > 0.5) is green.
    let texture = ImageTexture::new(
        2,
        2,
        vec![
            [0.0, 1.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0],
            [1.0, 1.0, 1.0],
        ],
    )
    .unwrap();
    assert_eq!(texture.sample(0.25, 0.75), [0.0, 1.0, 0.0]);
    let scene = Scene::new(&[red, textured]);
    let lighting = Lighting {
        ambient: 1.0,
        diffuse: 0.0,
        ..Lighting::default()
    };
    for (mesh, material, expected) in [
        (0, Material::VertexColors, [255, 0, 0]),
        (1, Material::Image(texture), [0, 255, 0]),
    ] {
        let instances = [Instance::new(mesh, Isometry3::translation(0.0, 0.0, 0.4))];
        let out = scene
            .render(&camera, &instances, Window::full(&camera))
            .unwrap();
        let rgb = scene
            .shade(&camera, &instances, &[material], &lighting, &out)
            .unwrap();
        let centre = (30 * camera.width + 40) as usize;
        assert_eq!(rgb[centre], expected);
    }
    // A mesh without colours cannot be shaded with vertex colours.
    let scene = Scene::new(&[mesh]);
    let instances = [Instance::new(0, Isometry3::translation(0.0, 0.0, 0.4))];
    let out = scene
        .render(&camera, &instances, Window::full(&camera))
        .unwrap();
    assert!(matches!(
        scene.shade(
            &camera,
            &instances,
            &[Material::VertexColors],
            &lighting,
            &out
        ),
        Err(RenderError::RenderingMismatch { .. })
    ));
    assert!(matches!(
        scene.shade(&camera, &instances, &[], &lighting, &out),
        Err(RenderError::RenderingMismatch { .. })
    ));
    assert!(ImageTexture::new(2, 2, vec![[0.0; 3]; 3]).is_err());
}

#[test]
fn the_patch_texture_breaks_visual_but_not_geometric_symmetry() {
    let camera = camera();
    let can = Primitive::Cylinder {
        radius: 0.035,
        height: 0.1,
        segments: 360,
    };
    let scene = Scene::new(&[can.mesh().unwrap()]);
    let base = pose(1.2, 0.3, 0.2);
    // A turn about the can's axis by a multiple of the tessellation step: the same geometry.
    let turn = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 100f64.to_radians());
    let material = [Material::Patches {
        cell: 0.02,
        seed: 7,
    }];
    let mut images = Vec::new();
    for pose in [base, base * turn] {
        let instances = [Instance::new(0, pose)];
        let out = scene
            .render(&camera, &instances, Window::full(&camera))
            .unwrap();
        let rgb = scene
            .shade(&camera, &instances, &material, &Lighting::default(), &out)
            .unwrap();
        images.push((out.depth, rgb));
    }
    let depth_differs = images[0]
        .0
        .iter()
        .zip(&images[1].0)
        .filter(|(a, b)| (*a - *b).abs() > 1e-4)
        .count();
    assert!(depth_differs <= 2, "{depth_differs}");
    let colour_differs = images[0]
        .1
        .iter()
        .zip(&images[1].1)
        .filter(|(a, b)| a != b)
        .count();
    let visible = images[0].0.iter().filter(|d| **d > 0.0).count();
    assert!(
        colour_differs > visible / 4,
        "{colour_differs} of {visible}"
    );
}

#[test]
fn a_coloured_light_and_its_highlight_follow_blinn_phong() {
    // A white sphere straight ahead, lit from the camera: at the pixel facing the camera n, l
    // and h all point back at it, so n·l = n·h = 1 and each channel is
    // albedo · (ambient + diffuse · colour) + specular · colour.
    let camera = camera();
    let scene = Scene::new(&[primitives::sphere(0.05, 5).unwrap()]);
    let instances = [Instance::new(0, Isometry3::translation(0.0, 0.0, 0.5))];
    let out = scene
        .render(&camera, &instances, Window::full(&camera))
        .unwrap();
    let colour = [1.0, 0.6, 0.2];
    let lighting = |specular| Lighting {
        towards_light: Vector3::new(0.0, 0.0, -1.0),
        ambient: 0.1,
        diffuse: 0.5,
        colour,
        specular,
        shininess: 30.0,
        background: [0, 0, 0],
    };
    let shade = |specular| {
        scene
            .shade(
                &camera,
                &instances,
                &[Material::Uniform([0.8; 3])],
                &lighting(specular),
                &out,
            )
            .unwrap()
    };
    let (matte, shiny) = (shade(0.0), shade(0.3));
    // The pixel nearest the sphere's centre's projection (40.2, 30.6).
    let centre = (30 * camera.width + 40) as usize;
    for k in 0..3 {
        let expected =
            |specular: f32| 255.0 * (0.8 * (0.1 + 0.5 * colour[k]) + specular * colour[k]);
        assert!(
            (f32::from(matte[centre][k]) - expected(0.0)).abs() <= 1.5,
            "{matte:?}"
        );
        assert!(
            (f32::from(shiny[centre][k]) - expected(0.3)).abs() <= 2.5,
            "{k}"
        );
    }
    // The highlight is a spot: near the rim (n·h small) both agree within rounding.
    let rim = (30 * camera.width + 40 + 35) as usize;
    assert!(out.instance[rim].is_some());
    for k in 0..3 {
        assert!(
            matte[rim][k].abs_diff(shiny[rim][k]) <= 2,
            "{:?} {:?}",
            matte[rim],
            shiny[rim]
        );
    }
}

#[test]
fn projected_textures_repeat_over_model_space_on_meshes_without_uvs() {
    // A 64² image, red on its left half (u < 0.5) and green on its right, repeated every 0.1 m
    // on a 5 cm cube facing the camera: on the face, u = x / 0.1 wraps to [0.75, 1) for x < 0
    // (green) and lies in [0, 0.25] for x > 0 (red).
    let camera = camera();
    let cube = primitives::cuboid([0.05, 0.05, 0.05]).unwrap();
    assert!(cube.uvs().is_none());
    let texels = (0..64 * 64)
        .map(|i| {
            if i % 64 < 32 {
                [1.0, 0.0, 0.0]
            } else {
                [0.0, 1.0, 0.0]
            }
        })
        .collect();
    let texture = ImageTexture::new(64, 64, texels).unwrap();
    let scene = Scene::new(&[cube]);
    let pose = Isometry3::translation(0.0, 0.0, 0.4);
    let instances = [Instance::new(0, pose)];
    let out = scene
        .render(&camera, &instances, Window::full(&camera))
        .unwrap();
    let lighting = Lighting {
        ambient: 1.0,
        diffuse: 0.0,
        ..Lighting::default()
    };
    let material = Material::Projected { texture, tile: 0.1 };
    let rgb = scene
        .shade(&camera, &instances, &[material], &lighting, &out)
        .unwrap();
    for (x, expected) in [(-0.015, [0, 255, 0]), (0.015, [255, 0, 0])] {
        let pixel = camera
            .project(&(pose * Point3::new(x, 0.0, -0.025)))
            .unwrap();
        let i = (pixel.y as u32 * camera.width + pixel.x as u32) as usize;
        assert_eq!(rgb[i], expected, "x = {x}");
    }
}
