//! One synthetic frame: the object resting on a tabletop, a camera looking at it from a random
//! elevation and distance, optional distractors, rendered into BOP images and annotations.
use depth_render::{
    DepthSensor, ImageTexture, Instance, MaskErrors, Material, PinholeCamera, Primitive,
    RestingPose, Scene, TriangleMesh, Window, resting_poses,
};
use nalgebra::{Isometry3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};
use rand::{Rng, RngExt};

use bop_dataset::{GtInfo, mask_box};

use crate::SynthError;
use crate::randomize::Randomization;

/// Where the camera may be, relative to the object.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ViewRange {
    /// Elevation above the table plane (degrees), low and high.
    pub elevation_deg: (f64, f64),
    /// Distance from the object's centre (metres), low and high.
    pub distance: (f64, f64),
    /// The object's origin lies within this distance (metres) of the table's centre, in x and y.
    pub table_offset: f64,
    /// Where the object's centre appears in the image: 0 on the principal point (the camera
    /// looks at it), 1 anywhere its bounding sphere stays inside the image, fractions between.
    /// Real objects are seldom in the middle of the frame.
    pub off_centre: f64,
    /// The camera's roll about its line of sight, uniform within ±this many degrees (0: the
    /// table's horizon is level in the image).
    pub roll_deg: f64,
    /// How the object comes to rest on the table.
    pub placement: Placement,
}

/// How an object comes to rest on the table: on which face of its convex hull.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Placement {
    /// Dropped at random: each face by the chance of landing on it (the solid angle it
    /// subtends at the centre of mass). A tall box seldom lands on its end (the YCB sugar box's
    /// scan: 5% of the frames).
    #[default]
    Tossed,
    /// Set down by a person, as in scenes arranged for a camera: half the frames tossed, half on
    /// a face drawn uniformly from those the object stands on firmly ([`FIRM_TIPPING_DEG`]), so
    /// that a box stands on its end, and a can on its caps, as often as it lies on a side.
    Arranged,
    /// As in a cluttered scene: arranged, but a third of the frames tilted off the face drawn,
    /// by [`LEANING_DEG`] about a random horizontal axis, its lowest point on the table, as an
    /// object propped on a neighbour stands (YCB-Video's banana rests on another object with its
    /// long axis 28° from the table, a pose no face of its hull gives).
    Leaning,
}

impl Placement {
    /// `tossed`, `arranged` or `leaning`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Tossed => "tossed",
            Self::Arranged => "arranged",
            Self::Leaning => "leaning",
        }
    }

    /// Every placement.
    pub const ALL: [Self; 3] = [Self::Tossed, Self::Arranged, Self::Leaning];
}

/// The share of [`Placement::Leaning`]'s frames that lean.
pub const LEANING_SHARE: f64 = 1.0 / 3.0;

/// The range of a leaning object's tilt off the face it would rest on (degrees, drawn
/// uniformly): from barely off the face to half way to a box's next side.
pub const LEANING_DEG: (f64, f64) = (5.0, 45.0);

/// The least tipping angle (degrees, [`RestingPose::tipping_angle`]) of a face an object
/// stands on firmly. The YCB scans' boxes stand on their ends at 5–13° (their rounded edges
/// shrink the face a flat box of their size tips off at 15°), a mustard bottle upright at 13°; a
/// scan's bevel between two sides tips at 0–3°, a facet of a tessellated can's side at half the
/// angle between facets (under 4°: the can rolls).
pub const FIRM_TIPPING_DEG: f64 = 5.0;

impl Default for ViewRange {
    /// Elevation 15–80°, distance 0.5–1.0 m, object within ±5 cm of the table's centre, in
    /// the middle of a level image, tossed.
    fn default() -> Self {
        Self {
            elevation_deg: (15.0, 80.0),
            distance: (0.5, 1.0),
            table_offset: 0.05,
            off_centre: 0.0,
            roll_deg: 0.0,
            placement: Placement::Tossed,
        }
    }
}

/// The tabletop: 1.2 m square, facing up.
const TABLE: Primitive = Primitive::Plane {
    width: 1.2,
    depth: 1.2,
};

/// Distractor shapes: a cube, a tin and a carton a few centimetres across.
const DISTRACTORS: [Primitive; 3] = [
    Primitive::Cuboid {
        extents: [0.05, 0.05, 0.05],
    },
    Primitive::Cylinder {
        radius: 0.025,
        height: 0.08,
        segments: 32,
    },
    Primitive::Cuboid {
        extents: [0.04, 0.06, 0.1],
    },
];

/// A mesh with the ways it can rest on a table, the cumulative probabilities of those, the
/// faces it stands on firmly, and its vertices (for a leaning pose's lowest point).
struct Restable {
    poses: Vec<RestingPose>,
    cumulative: Vec<f64>,
    firm: Vec<usize>,
    vertices: Vec<Vector3<f64>>,
}

impl Restable {
    fn new(mesh: &TriangleMesh) -> Result<Self, SynthError> {
        let poses = resting_poses(mesh)?;
        let cumulative = poses
            .iter()
            .scan(0.0, |total, pose| {
                *total += pose.probability;
                Some(*total)
            })
            .collect();
        let firm = (0..poses.len())
            .filter(|&i| poses[i].tipping_angle >= FIRM_TIPPING_DEG.to_radians())
            .collect();
        Ok(Self {
            poses,
            cumulative,
            firm,
            vertices: mesh
                .positions()
                .iter()
                .map(|p| p.coords.cast::<f64>())
                .collect(),
        })
    }

    /// A table-from-model pose: a stable face drawn as `placement` says, a random yaw, the
    /// origin above `(x, y)`; a leaning one tilted off it. A tossed placement draws two
    /// numbers, an arranged one three, a leaning one four or six.
    fn place<R: Rng>(&self, placement: Placement, rng: &mut R, x: f64, y: f64) -> Isometry3<f64> {
        if placement == Placement::Leaning {
            let lean = rng.random::<f64>() < LEANING_SHARE;
            let resting = self.place(Placement::Arranged, rng, x, y);
            return if lean {
                self.tilted(&resting, rng)
            } else {
                resting
            };
        }
        let set_down = placement == Placement::Arranged && rng.random::<bool>();
        let draw = rng.random::<f64>();
        let face = if set_down && !self.firm.is_empty() {
            self.firm[((draw * self.firm.len() as f64) as usize).min(self.firm.len() - 1)]
        } else {
            let draw = draw * self.cumulative.last().copied().unwrap_or(1.0);
            self.cumulative
                .partition_point(|&c| c < draw)
                .min(self.poses.len() - 1)
        };
        let yaw = rng.random::<f64>() * std::f64::consts::TAU;
        self.poses[face].on_table(yaw, x, y)
    }

    /// `resting` tilted by an angle in [`LEANING_DEG`] about a random horizontal axis through
    /// the model's origin, then lowered or raised until its lowest vertex touches the table.
    fn tilted<R: Rng>(&self, resting: &Isometry3<f64>, rng: &mut R) -> Isometry3<f64> {
        let heading = rng.random::<f64>() * std::f64::consts::TAU;
        let (low, high) = LEANING_DEG;
        let angle = (low + (high - low) * rng.random::<f64>()).to_radians();
        let axis = Vector3::new(heading.cos(), heading.sin(), 0.0);
        let rotation = UnitQuaternion::from_scaled_axis(axis * angle) * resting.rotation;
        let lowest = self
            .vertices
            .iter()
            .map(|v| (rotation * v).z)
            .fold(f64::INFINITY, f64::min);
        let origin = resting.translation.vector;
        Isometry3::from_parts(Translation3::new(origin.x, origin.y, -lowest), rotation)
    }
}

/// Renders frames of one object: the scene (object, table, distractors, occluding panel) is
/// built once.
pub struct FrameRenderer {
    scene: Scene,
    object: Restable,
    distractors: Vec<Restable>,
    /// The panel only occluders use (the scene's last mesh), standing on its `−z` face.
    panel: RestingPose,
    /// The object's bounding-box corners (model frame).
    corners: [Point3<f64>; 8],
    /// The distractors' bounding-box corners (their model frames).
    distractor_corners: Vec<[Point3<f64>; 8]>,
    /// The panel's.
    panel_corners: [Point3<f64>; 8],
    centre: Point3<f64>,
    /// Half the bounding box's diagonal (metres).
    radius: f64,
}

/// The images and annotations of one frame.
pub struct Frame {
    /// Shaded colour, row-major.
    pub rgb: Vec<[u8; 3]>,
    /// z-depth in metres (0: no reading), as the sensor reads it when there is one.
    pub depth: Vec<f32>,
    /// The object's full silhouette.
    pub mask: Vec<bool>,
    /// Its visible part (with a detector's errors when asked for).
    pub mask_visib: Vec<bool>,
    /// Model→camera pose (metres).
    pub pose: Isometry3<f64>,
    /// Boxes and pixel counts.
    pub info: GtInfo,
}

/// What one frame looks like beyond geometry.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameStyle {
    /// The object's material.
    pub material: Material,
    /// The object wears a surface drawn per frame instead of `material`, as distractors do
    /// under `randomization.textures` (a flat colour, a procedural texture or one of
    /// `borrowed_textures`): what [`crate::synthesize`] gives, with textures randomised, a mesh
    /// that brings no surface of its own, whose real look is unknown.
    pub random_surface: bool,
    /// Distractor objects on the table around it.
    pub distractors: usize,
    /// Objects on the table between it and the camera, hiding part of it: distractor shapes or
    /// an upright panel its own size.
    pub occluders: usize,
    /// What the depth camera reads, or clean depth.
    pub sensor: Option<DepthSensor>,
    /// A detector's errors on the visible mask, or the exact mask.
    pub mask_errors: Option<MaskErrors>,
    /// The parts of the frame's look drawn at random ([`Randomization::NONE`]: the plain look).
    pub randomization: Randomization,
    /// Textures that distractors may wear when `randomization.textures` is on (the objects'
    /// own).
    pub borrowed_textures: Vec<ImageTexture>,
}

impl FrameStyle {
    /// The plain look of an object of `material`: alone on the table, clean depth, the exact
    /// mask, nothing drawn at random. Other styles start from it (`..FrameStyle::plain(m)`).
    pub fn plain(material: Material) -> Self {
        Self {
            material,
            random_surface: false,
            distractors: 0,
            occluders: 0,
            sensor: None,
            mask_errors: None,
            randomization: Randomization::NONE,
            borrowed_textures: Vec::new(),
        }
    }
}

impl FrameRenderer {
    /// A renderer of frames of `mesh` (metres).
    pub fn new(mesh: &TriangleMesh) -> Result<Self, SynthError> {
        let distractor_meshes = DISTRACTORS
            .iter()
            .map(Primitive::mesh)
            .collect::<Result<Vec<_>, _>>()?;
        let mut meshes = vec![mesh.clone(), TABLE.mesh()?];
        meshes.extend(distractor_meshes.iter().cloned());
        let (low, high) = mesh.bounds();
        let (low, high) = (low.cast::<f64>(), high.cast::<f64>());
        let radius = (high - low).norm() / 2.0;
        // A panel as wide as the object's bounding radius and 1.6 times as tall, standing:
        // the small distractors cannot hide more than their 10 cm of a tall object.
        let panel = Primitive::Cuboid {
            extents: [radius, 0.02, 1.6 * radius],
        }
        .mesh()?;
        let panel_corners = box_corners(&panel);
        meshes.push(panel);
        Ok(Self {
            scene: Scene::new(&meshes),
            object: Restable::new(mesh)?,
            distractors: distractor_meshes
                .iter()
                .map(Restable::new)
                .collect::<Result<_, _>>()?,
            panel: RestingPose {
                normal: -Vector3::z_axis(),
                offset: 0.8 * radius,
                probability: 1.0,
                // Upright on its end, 2 cm thick.
                tipping_angle: 0.01f64.atan2(0.8 * radius),
            },
            corners: box_corners(mesh),
            distractor_corners: distractor_meshes.iter().map(box_corners).collect(),
            panel_corners,
            centre: nalgebra::center(&low, &high),
            radius,
        })
    }

    /// Draws and renders one frame with `rng`.
    pub fn render<R: Rng>(
        &self,
        camera: &PinholeCamera,
        view: &ViewRange,
        style: &FrameStyle,
        rng: &mut R,
    ) -> Result<Frame, SynthError> {
        let mut offset = || (rng.random::<f64>() * 2.0 - 1.0) * view.table_offset;
        let (x, y) = (offset(), offset());
        let world_from_object = self.object.place(view.placement, rng, x, y);
        let centre = world_from_object * self.centre;
        let camera_from_world = look_at(&centre, view, rng);
        let camera_from_world = reframe(camera_from_world, &centre, self.radius, camera, view, rng);
        let pose = camera_from_world * world_from_object;
        let others =
            self.place_others(style, (&world_from_object, (x, y)), &camera_from_world, rng);
        // The look is drawn after the geometry: the same seed shows the same scene.
        let random = &style.randomization;
        let look = random.draw_look(rng, camera.width, camera.height);
        let mut instances = vec![Instance::new(0, pose), Instance::new(1, camera_from_world)];
        let surface = if style.random_surface {
            Randomization::draw_surface(rng, &style.borrowed_textures)
        } else {
            style.material.clone()
        };
        let mut materials = vec![surface, look.table];
        for (instance, material) in others {
            instances.push(instance);
            materials.push(if random.textures {
                Randomization::draw_surface(rng, &style.borrowed_textures)
            } else {
                material
            });
        }
        let full = Window::full(camera);
        let rendering = self.scene.render(camera, &instances, full)?;
        let mut rgb =
            self.scene
                .shade(camera, &instances, &materials, &look.lighting, &rendering)?;
        if let Some(background) = &look.background {
            for ((pixel, hit), behind) in rgb.iter_mut().zip(&rendering.instance).zip(background) {
                if hit.is_none() {
                    *pixel = *behind;
                }
            }
        }
        if let Some(chain) = &look.camera {
            rgb = chain.apply(&rgb, camera.width, camera.height, rng.random())?;
        }
        let mask_visib: Vec<bool> = rendering.instance.iter().map(|&i| i == Some(0)).collect();
        let mask = self.silhouette(camera, &pose)?;
        let width = camera.width as usize;
        let depth = match &style.sensor {
            Some(sensor) => sensor.apply(&rendering.depth, camera, rng.random()),
            None => rendering.depth,
        };
        // The boxes and pixel counts are the true masks'.
        let info = gt_info(&mask, &mask_visib, &depth, width);
        let mask_visib = match &style.mask_errors {
            Some(errors) => errors.apply(&mask_visib, width, rng.random()),
            None => mask_visib,
        };
        Ok(Frame {
            rgb,
            depth,
            mask,
            mask_visib,
            pose,
            info,
        })
    }

    /// The distractors and occluders of a frame (`style`), placed on the table around the
    /// object (its table pose and origin) seen by `camera_from_world`: each one's instance and
    /// random flat colour.
    fn place_others<R: Rng>(
        &self,
        style: &FrameStyle,
        (world_from_object, (x, y)): (&Isometry3<f64>, (f64, f64)),
        camera_from_world: &Isometry3<f64>,
        rng: &mut R,
    ) -> Vec<(Instance, Material)> {
        // The camera's direction from the object, on the table.
        let eye = camera_from_world.inverse() * Point3::origin();
        let towards_camera = (eye.y - y).atan2(eye.x - x);
        let mut others = Vec::with_capacity(style.distractors + style.occluders);
        for k in 0..style.distractors + style.occluders {
            // Distractors are the small shapes; occluders those or the panel.
            let kinds = DISTRACTORS.len() + usize::from(k >= style.distractors);
            let kind = rng.random_range(0..kinds);
            let (angle, reach) = if k < style.distractors {
                let angle = rng.random::<f64>() * std::f64::consts::TAU;
                (angle, 0.1 + 0.08 * rng.random::<f64>())
            } else {
                // Within 20° of the line of sight, 7–10 cm in front of the object's origin.
                let spread = (rng.random::<f64>() * 2.0 - 1.0) * 20f64.to_radians();
                (towards_camera + spread, 0.07 + 0.03 * rng.random::<f64>())
            };
            // Stood at the table's origin first, then moved out along `angle`.
            let (standing, corners) = self.standing_at_origin(kind, rng, |rng| {
                // The panel faces the camera, give or take 30°.
                let turn = (rng.random::<f64>() * 2.0 - 1.0) * 30f64.to_radians();
                towards_camera - std::f64::consts::FRAC_PI_2 + turn
            });
            let placed = place_beside(
                (&standing, corners),
                (world_from_object, &self.corners),
                (x, y),
                angle,
                reach,
            );
            let colour = std::array::from_fn(|_| 0.2 + 0.7 * rng.random::<f32>());
            others.push((
                Instance::new(2 + kind, camera_from_world * placed),
                Material::Uniform(colour),
            ));
        }
        others
    }

    /// The object's full silhouette at `pose` (nothing in front of it), over the whole image.
    fn silhouette(
        &self,
        camera: &PinholeCamera,
        pose: &Isometry3<f64>,
    ) -> Result<Vec<bool>, SynthError> {
        let alone = self.scene.render(
            camera,
            &[Instance::new(0, *pose)],
            self.window(camera, pose),
        )?;
        let width = camera.width as usize;
        let mut mask = vec![false; width * camera.height as usize];
        let window_width = alone.window.width() as usize;
        for (i, hit) in alone.instance.iter().enumerate() {
            if hit.is_some() {
                let (u, v) = (
                    alone.window.u0 as usize + i % window_width,
                    alone.window.v0 as usize + i / window_width,
                );
                mask[v * width + u] = true;
            }
        }
        Ok(mask)
    }

    /// The pixels the object's bounding box projects to (the whole image when part of it is
    /// behind the camera).
    fn window(&self, camera: &PinholeCamera, pose: &Isometry3<f64>) -> Window {
        let projected: Option<Vec<_>> = self
            .corners
            .iter()
            .map(|corner| camera.project(&(pose * corner)))
            .collect();
        let Some(projected) = projected else {
            return Window::full(camera);
        };
        let (mut low, mut high) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in &projected {
            for axis in 0..2 {
                low[axis] = low[axis].min(p[axis]);
                high[axis] = high[axis].max(p[axis]);
            }
        }
        let clamp = |v: f64, size: u32| v.clamp(0.0, f64::from(size)) as u32;
        Window {
            u0: clamp(low[0].floor(), camera.width),
            v0: clamp(low[1].floor(), camera.height),
            u1: clamp(high[0].ceil() + 1.0, camera.width),
            v1: clamp(high[1].ceil() + 1.0, camera.height),
        }
    }

    /// Distractor shape `kind`, or the panel for `kind == DISTRACTORS.len()` turned to the yaw
    /// `panel_yaw` draws (called for the panel only), standing at the table's origin: its table
    /// pose and its bounding-box corners, for [`place_beside`].
    fn standing_at_origin<R: Rng>(
        &self,
        kind: usize,
        rng: &mut R,
        panel_yaw: impl FnOnce(&mut R) -> f64,
    ) -> (Isometry3<f64>, &[Point3<f64>; 8]) {
        if kind == DISTRACTORS.len() {
            let yaw = panel_yaw(rng);
            (self.panel.on_table(yaw, 0.0, 0.0), &self.panel_corners)
        } else {
            (
                self.distractors[kind].place(Placement::Tossed, rng, 0.0, 0.0),
                &self.distractor_corners[kind],
            )
        }
    }
}

/// The corners of `mesh`'s axis-aligned bounding box.
fn box_corners(mesh: &TriangleMesh) -> [Point3<f64>; 8] {
    let (low, high) = mesh.bounds();
    let (low, high) = (low.cast::<f64>(), high.cast::<f64>());
    std::array::from_fn(|i| {
        Point3::new(
            if i & 1 == 0 { low.x } else { high.x },
            if i & 2 == 0 { low.y } else { high.y },
            if i & 4 == 0 { low.z } else { high.z },
        )
    })
}

/// Gap (metres) kept between the bounding boxes of the object and of a thing placed beside it.
const CLEARANCE: f64 = 0.005;

/// The table pose of a thing standing at the table's origin (`thing`: its table pose and
/// bounding-box corners) moved out from the object's origin `(x, y)` along the table direction
/// `angle`: by `reach`, or farther where their bounding boxes, seen from above, would come
/// within [`CLEARANCE`] of each other along that direction (a panel 7 cm in front of the centre
/// of a box 21 cm long stood inside it).
fn place_beside(
    thing: (&Isometry3<f64>, &[Point3<f64>; 8]),
    object: (&Isometry3<f64>, &[Point3<f64>; 8]),
    (x, y): (f64, f64),
    angle: f64,
    reach: f64,
) -> Isometry3<f64> {
    let (dx, dy) = (angle.cos(), angle.sin());
    let support = |(pose, corners): (&Isometry3<f64>, &[Point3<f64>; 8]), sign: f64| {
        corners
            .iter()
            .map(|c| {
                let p = pose * c;
                sign * (p.x * dx + p.y * dy)
            })
            .fold(f64::NEG_INFINITY, f64::max)
    };
    let object_reach = support(object, 1.0) - (x * dx + y * dy);
    let reach = reach.max(object_reach + support(thing, -1.0) + CLEARANCE);
    Translation3::new(x + reach * dx, y + reach * dy, 0.0) * thing.0
}

/// A camera-from-world pose looking at `target` from a random elevation, azimuth and
/// distance in `view`, the image's x-axis level (OpenCV axes: x right, y down, z forward).
fn look_at<R: Rng>(target: &Point3<f64>, view: &ViewRange, rng: &mut R) -> Isometry3<f64> {
    let mut between = |(low, high): (f64, f64)| low + (high - low) * rng.random::<f64>();
    let elevation = between(view.elevation_deg).to_radians();
    let distance = between(view.distance);
    let azimuth = between((0.0, std::f64::consts::TAU));
    let eye = target
        + distance
            * Vector3::new(
                elevation.cos() * azimuth.cos(),
                elevation.cos() * azimuth.sin(),
                elevation.sin(),
            );
    let forward = (target - eye).normalize();
    let right = forward.cross(&Vector3::z()).normalize();
    let down = forward.cross(&right);
    let camera_from_world = Rotation3::from_matrix_unchecked(nalgebra::Matrix3::from_rows(&[
        right.transpose(),
        down.transpose(),
        forward.transpose(),
    ]));
    let rotation = UnitQuaternion::from_rotation_matrix(&camera_from_world);
    Isometry3::from_parts(Translation3::from(-(rotation * eye.coords)), rotation)
}

/// `camera_from_world` (looking at `target`) turned about its centre so that `target` appears
/// at a random pixel within `view.off_centre` of the room a bounding sphere of `radius` leaves
/// in the image, and rolled by up to `view.roll_deg`; unchanged, drawing nothing from `rng`,
/// when both are 0.
fn reframe<R: Rng>(
    camera_from_world: Isometry3<f64>,
    target: &Point3<f64>,
    radius: f64,
    camera: &PinholeCamera,
    view: &ViewRange,
    rng: &mut R,
) -> Isometry3<f64> {
    if view.off_centre == 0.0 && view.roll_deg == 0.0 {
        return camera_from_world;
    }
    let mut symmetric = |half: f64| (rng.random::<f64>() * 2.0 - 1.0) * half;
    let roll = symmetric(view.roll_deg.to_radians());
    let depth = (camera_from_world * target).z.max(1e-9);
    // The room on each side of the principal point, less the sphere's projected radius.
    let room = |centre: f64, size: u32, focal: f64| {
        (centre.min(f64::from(size) - centre) - focal * radius / depth).max(0.0) * view.off_centre
    };
    let u = symmetric(room(camera.cx, camera.width, camera.fx)) / camera.fx;
    let v = symmetric(room(camera.cy, camera.height, camera.fy)) / camera.fy;
    let aim = UnitQuaternion::rotation_between(&Vector3::z(), &Vector3::new(u, v, 1.0))
        .unwrap_or_else(UnitQuaternion::identity);
    let turn = aim * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), roll);
    Isometry3::from_parts(Translation3::identity(), turn) * camera_from_world
}

/// BOP's boxes `[x, y, w, h]` and pixel counts of a frame; `w` and `h` are the last pixel's
/// offsets from the first, as the BOP toolkit's `calc_2d_bbox` writes them.
fn gt_info(mask: &[bool], mask_visib: &[bool], depth: &[f32], width: usize) -> GtInfo {
    let bbox = |pixels: &[bool]| match mask_box(pixels, width) {
        Some([u0, v0, u1, v1]) => [u0, v0, u1 - 1 - u0, v1 - 1 - v0].map(i64::from),
        None => [-1; 4],
    };
    let count = |pixels: &[bool], valid_only: bool| {
        pixels
            .iter()
            .zip(depth)
            .filter(|&(&m, &d)| m && (!valid_only || d > 0.0))
            .count() as u64
    };
    let (all, visib) = (count(mask, false), count(mask_visib, false));
    GtInfo {
        bbox_obj: bbox(mask),
        bbox_visib: bbox(mask_visib),
        px_count_all: all,
        px_count_valid: count(mask, true),
        px_count_visib: visib,
        visib_fract: if all == 0 {
            0.0
        } else {
            visib as f64 / all as f64
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    /// The visible fractions of 24 frames of `object` with these distractors and occluders.
    fn visible_fractions(
        object: crate::ObjectKind,
        distractors: usize,
        occluders: usize,
    ) -> Vec<f64> {
        let object = crate::SynthObject::built_in(object).unwrap();
        let renderer = FrameRenderer::new(&object.mesh).unwrap();
        let camera = crate::SynthOptions::t_less_camera().camera;
        let style = FrameStyle {
            distractors,
            occluders,
            ..FrameStyle::plain(Material::Uniform(object.colour))
        };
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        (0..24)
            .map(|_| {
                let frame = renderer
                    .render(&camera, &ViewRange::default(), &style, &mut rng)
                    .unwrap();
                frame.info.visib_fract
            })
            .collect()
    }

    #[test]
    fn occluders_stand_between_the_object_and_the_camera() {
        let visible = |distractors, occluders| {
            visible_fractions(crate::ObjectKind::Bowl, distractors, occluders)
        };
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        // Two distractors anywhere around it hide less than two in front of it.
        let (around, in_front) = (visible(2, 0), visible(0, 2));
        assert!(
            mean(&in_front) < mean(&around) - 0.05,
            "{around:?} {in_front:?}"
        );
        // The floor: each occluder is the panel one time in four (one of four shapes), so
        // about 24 · (1 − (3/4)²) ≈ 10 of the frames have one. Standing about 10 cm in front of
        // the bowl and 185 mm tall (1.6 times the bowl's bounding radius, 115 mm, which is its
        // width), it hides the middle of the 53 mm bowl from cameras below about 58° of
        // elevation (26 mm + 100 mm · tan 58° = 185 mm): two thirds of the 15–80° drawn, about 7
        // frames, each hiding well over 30% of the bowl. At least 3 leaves room for panels
        // turned aside (±20° of the line of sight) and for the draws.
        assert!(
            in_front.iter().filter(|&&v| v < 0.7).count() >= 3,
            "{in_front:?}"
        );
        // The panel hides even the tall box (21 cm) to under 45% at times. The floor: as above,
        // about 10 of 24 frames have a panel (135 mm wide, 216 mm tall for the box), which
        // stands between the camera and the middle of the box (lying, 60 mm tall, or on its
        // side, 158 mm, about 13 cm in front) below about 55° of elevation, in about 6 frames;
        // it hides over 55% of the box only where it covers the box's width too (its 135 mm
        // against the 158–210 mm sides seen broadside), say a third of those: at least 2.
        let tall = visible_fractions(crate::ObjectKind::Box, 0, 2);
        assert!(tall.iter().filter(|&&v| v < 0.45).count() >= 2, "{tall:?}");
    }

    /// Whether a point lies inside the box spanned by `corners` (`corners[0]` the low corner,
    /// `corners[7]` the high one).
    fn inside(p: &Point3<f64>, corners: &[Point3<f64>; 8]) -> bool {
        (0..3).all(|a| corners[0][a] < p[a] && p[a] < corners[7][a])
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]

        /// A distractor or the panel, moved out by `place_beside` from wherever it was asked to
        /// stand, never enters the object's bounding box (points of its own box, taken into
        /// the object's frame, stay outside): the box lying with its 21 cm side towards them.
        #[test]
        fn things_placed_beside_the_object_stay_out_of_it(seed in proptest::prelude::any::<u64>()) {
            let object = crate::SynthObject::built_in(crate::ObjectKind::Box).unwrap();
            let renderer = FrameRenderer::new(&object.mesh).unwrap();
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let (x, y) = (rng.random::<f64>() * 0.1 - 0.05, rng.random::<f64>() * 0.1 - 0.05);
            let world_from_object = renderer.object.place(Placement::Tossed, &mut rng, x, y);
            let angle = rng.random::<f64>() * std::f64::consts::TAU;
            let kind = rng.random_range(0..=DISTRACTORS.len());
            let (standing, corners) =
                renderer.standing_at_origin(kind, &mut rng, |rng| rng.random::<f64>() * 6.3);
            let asked = 0.1 * rng.random::<f64>();
            let placed = place_beside(
                (&standing, corners),
                (&world_from_object, &renderer.corners),
                (x, y),
                angle,
                asked,
            );
            // Along `angle`, at least as far as asked.
            let moved = placed.translation.vector.xy() - nalgebra::Vector2::new(x, y);
            let direction = nalgebra::Vector2::new(angle.cos(), angle.sin());
            proptest::prop_assert!((moved - direction * moved.norm()).norm() < 1e-12, "{moved}");
            proptest::prop_assert!(moved.norm() >= asked - 1e-12, "{moved} {asked}");
            let object_from_thing = world_from_object.inverse() * placed;
            for i in 0..=4 {
                for j in 0..=4 {
                    for k in 0..=4 {
                        let t = |n: usize| n as f64 / 4.0;
                        let local = Point3::from(
                            corners[0].coords
                                + (corners[7] - corners[0])
                                    .component_mul(&Vector3::new(t(i), t(j), t(k))),
                        );
                        let p = object_from_thing * local;
                        proptest::prop_assert!(!inside(&p, &renderer.corners), "{p} inside");
                    }
                }
            }
        }
    }

    /// Tossed, a face comes up as often as its probability says; arranged, half as often plus
    /// half of a uniform share of the firm faces; leaning, as arranged in the frames that do not
    /// lean ([`LEANING_SHARE`] lean): frequencies over 20,000 draws of the built-in box (whose
    /// six faces are all firm) and a can (firm only on its caps), within 4.5 binomial standard
    /// deviations.
    #[test]
    fn arranged_objects_stand_on_their_firm_faces_as_often_as_on_any() {
        for kind in [crate::ObjectKind::Box, crate::ObjectKind::Can] {
            let object = crate::SynthObject::built_in(kind).unwrap();
            let restable = Restable::new(&object.mesh).unwrap();
            let firm = restable.firm.len() as f64;
            assert_eq!(
                firm,
                if kind == crate::ObjectKind::Box {
                    6.0
                } else {
                    2.0
                }
            );
            for placement in Placement::ALL {
                let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
                let draws = 20_000;
                // One count per face, the last for frames on none (leaning).
                let mut counts = vec![0usize; restable.poses.len() + 1];
                for _ in 0..draws {
                    let pose = restable.place(placement, &mut rng, 0.0, 0.0);
                    let down = pose.inverse_transform_vector(&-Vector3::z());
                    let face = restable
                        .poses
                        .iter()
                        .position(|p| (p.normal.into_inner() - down).norm() < 1e-9)
                        .unwrap_or(restable.poses.len());
                    counts[face] += 1;
                }
                let upright = match placement {
                    Placement::Leaning => 1.0 - LEANING_SHARE,
                    _ => 1.0,
                };
                let mut expectations: Vec<f64> = restable
                    .poses
                    .iter()
                    .enumerate()
                    .map(|(i, pose)| {
                        let uniform = if restable.firm.contains(&i) {
                            1.0 / firm
                        } else {
                            0.0
                        };
                        upright
                            * match placement {
                                Placement::Tossed => pose.probability,
                                Placement::Arranged | Placement::Leaning => {
                                    0.5 * pose.probability + 0.5 * uniform
                                }
                            }
                    })
                    .collect();
                expectations.push(1.0 - upright);
                for (i, &expected) in expectations.iter().enumerate() {
                    let seen = counts[i] as f64 / f64::from(draws);
                    let sigma = (expected * (1.0 - expected) / f64::from(draws)).sqrt();
                    assert!(
                        (seen - expected).abs() <= 4.5 * sigma + 1e-12,
                        "{kind:?} {placement:?} face {i}: {seen} against {expected}"
                    );
                }
            }
        }
    }

    /// A leaning box (the built-in one, whose faces are 90° apart) is tilted off the nearest
    /// face by 5–45°, spread over that range, and touches the table without passing through it:
    /// the lowest corner of its bounding box (from the mesh's bounds, not its vertex list) at
    /// height 0, its origin above the point asked for.
    #[test]
    fn leaning_objects_tilt_off_a_face_and_touch_the_table() {
        let object = crate::SynthObject::built_in(crate::ObjectKind::Box).unwrap();
        let restable = Restable::new(&object.mesh).unwrap();
        let corners = box_corners(&object.mesh);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(17);
        let mut tilts = Vec::new();
        for _ in 0..3_000 {
            let pose = restable.place(Placement::Leaning, &mut rng, 0.03, -0.02);
            let down = pose.inverse_transform_vector(&-Vector3::z());
            let nearest = restable
                .poses
                .iter()
                .map(|p| p.normal.angle(&down).to_degrees())
                .fold(f64::INFINITY, f64::min);
            let lowest = corners
                .iter()
                .map(|c| (pose * c).z)
                .fold(f64::INFINITY, f64::min);
            assert!(lowest.abs() < 1e-9, "lowest corner at {lowest}");
            let origin = pose.translation.vector;
            assert!((origin.x - 0.03).abs() < 1e-12 && (origin.y + 0.02).abs() < 1e-12);
            if nearest > 1e-6 {
                assert!(
                    (LEANING_DEG.0 - 1e-6..=LEANING_DEG.1 + 1e-6).contains(&nearest),
                    "tilted {nearest}°"
                );
                tilts.push(nearest);
            }
        }
        // A third lean: 1,000 expected, binomial σ 26.
        assert!((880..=1_120).contains(&tilts.len()), "{} lean", tilts.len());
        // Uniform over 5–45°: mean 25°, σ of the mean 11.5° / √1000 = 0.4°.
        let mean = tilts.iter().sum::<f64>() / tilts.len() as f64;
        assert!((mean - 25.0).abs() < 1.6, "mean tilt {mean}°");
        let (least, most) = tilts
            .iter()
            .fold((f64::INFINITY, 0.0f64), |(l, m), &t| (l.min(t), m.max(t)));
        assert!(least < 6.0 && most > 44.0, "{least}–{most}°");
    }

    #[test]
    fn the_camera_looks_at_the_target_from_the_range_asked_for() {
        let view = ViewRange::default();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let target = Point3::new(0.02, -0.03, 0.05);
        for _ in 0..50 {
            let camera_from_world = look_at(&target, &view, &mut rng);
            let seen = camera_from_world * target;
            assert!(seen.x.abs() < 1e-9 && seen.y.abs() < 1e-9, "{seen}");
            assert!((0.5..=1.0).contains(&seen.z));
            // The world's up points up in the image (negative y), and the elevation is in range.
            let up = camera_from_world.rotation * Vector3::z();
            assert!(up.y < 0.0 && up.x.abs() < 1e-9);
            let eye = camera_from_world.inverse() * Point3::origin();
            let elevation = ((eye - target).z / (eye - target).norm())
                .asin()
                .to_degrees();
            assert!(
                (15.0 - 1e-9..=80.0 + 1e-9).contains(&elevation),
                "{elevation}"
            );
        }
    }

    #[test]
    fn reframing_moves_the_object_anywhere_inside_the_image_and_rolls_the_camera() {
        let camera = crate::SynthOptions::t_less_camera().camera;
        let target = Point3::new(0.02, -0.03, 0.05);
        let radius = 0.08;
        let level = ViewRange::default();
        let moved = ViewRange {
            off_centre: 1.0,
            roll_deg: 30.0,
            ..level
        };
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let (mut widest, mut steepest) = (0.0f64, 0.0f64);
        for _ in 0..200 {
            let aimed = look_at(&target, &level, &mut rng);
            // Neither option asked: the camera is left as it was.
            let same = reframe(aimed, &target, radius, &camera, &level, &mut rng);
            assert!((same.to_homogeneous() - aimed.to_homogeneous()).abs().max() < 1e-12);
            let turned = reframe(aimed, &target, radius, &camera, &moved, &mut rng);
            // Turned about the camera's centre: the distance to the target is kept.
            let seen = turned * target;
            assert!((seen.coords.norm() - (aimed * target).coords.norm()).abs() < 1e-9);
            // The bounding sphere stays inside the image.
            let pixel = camera.project(&seen).unwrap();
            let margin = camera.fx * radius / seen.z;
            assert!(pixel.x > margin * 0.9 && pixel.x < f64::from(camera.width) - margin * 0.9);
            assert!(pixel.y > margin * 0.9 && pixel.y < f64::from(camera.height) - margin * 0.9);
            widest = widest.max((pixel.x - camera.cx).abs());
            // The turn is the shortest one that moves the line of sight onto the target after a
            // roll about the line of sight of at most 30°.
            let turn = turned.rotation * aimed.rotation.inverse();
            let sight = turn * Vector3::z();
            let aim = UnitQuaternion::rotation_between(&Vector3::z(), &sight).unwrap();
            let roll = aim.inverse() * turn;
            let axis = roll.axis().map_or(Vector3::z(), |a| a.into_inner());
            assert!(roll.angle() < 1e-9 || axis.z.abs() > 1.0 - 1e-9, "{axis}");
            steepest = steepest.max(roll.angle().to_degrees());
        }
        assert!(widest > 100.0, "the centre moved at most {widest} px");
        assert!((25.0..=30.0).contains(&steepest), "roll {steepest}°");
    }
}
