//! Domain randomisation of a frame's look (Tobin et al. 2017; Tremblay et al. 2018): random
//! lights, procedural table and background textures, textured distractors and occluders, and a
//! random colour camera. The object keeps its own appearance; the geometry of a frame (poses,
//! distractors' places) is drawn before its look, so a randomised dataset shows the same scenes
//! as a plain one with the same seed.
use depth_render::{ImageChain, ImageTexture, Lighting, Material};
use nalgebra::Vector3;
use rand::{Rng, RngExt};

use crate::SynthError;
use crate::procedural::random_pattern;

/// Which parts of a frame's look are drawn at random, per frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Randomization {
    /// The light's direction, strength, colour, the ambient share and a specular highlight.
    pub lights: bool,
    /// Procedural textures on the table and behind it.
    pub backgrounds: bool,
    /// Distractors and occluders in procedural textures or the objects' own, not flat colours;
    /// and in the texture variant, an object whose mesh brings no surface of its own (no
    /// texture, no vertex colours) in a surface drawn as theirs are, per frame.
    pub textures: bool,
    /// The colour camera: blur, exposure, white balance, noise, tone curve, JPEG quality.
    pub camera: bool,
}

/// The parts' names, in the order of [`Randomization::names`].
const PARTS: [&str; 4] = ["lights", "backgrounds", "textures", "camera"];

impl Randomization {
    /// Every part.
    pub const ALL: Self = Self {
        lights: true,
        backgrounds: true,
        textures: true,
        camera: true,
    };

    /// No part: the plain look (one white light, a grey table, black background).
    pub const NONE: Self = Self {
        lights: false,
        backgrounds: false,
        textures: false,
        camera: false,
    };

    /// Parses `all`, `none` or a comma-separated list of `lights`, `backgrounds`, `textures`
    /// and `camera`.
    pub fn parse(list: &str) -> Result<Self, SynthError> {
        match list.trim() {
            "all" => return Ok(Self::ALL),
            "none" => return Ok(Self::NONE),
            _ => {}
        }
        let mut parts = Self::NONE;
        for name in list.split(',').map(str::trim) {
            let flag = match name {
                "lights" => &mut parts.lights,
                "backgrounds" => &mut parts.backgrounds,
                "textures" => &mut parts.textures,
                "camera" => &mut parts.camera,
                _ => {
                    return Err(SynthError::option(
                        "randomize",
                        format!("unknown part {name:?}: expected all, none or a list of {PARTS:?}"),
                    ));
                }
            };
            *flag = true;
        }
        Ok(parts)
    }

    /// The names of the parts that are on.
    pub fn names(&self) -> Vec<&'static str> {
        let on = [self.lights, self.backgrounds, self.textures, self.camera];
        PARTS.iter().zip(on).filter(|p| p.1).map(|p| *p.0).collect()
    }

    /// Whether no part is on.
    pub fn is_none(&self) -> bool {
        *self == Self::NONE
    }

    /// The look of one frame, drawn with `rng` for the parts that are on (nothing is drawn
    /// for the others); `width × height` is the image's size.
    pub(crate) fn draw_look<R: Rng>(&self, rng: &mut R, width: u32, height: u32) -> Look {
        let lighting = if self.lights {
            random_lighting(rng)
        } else {
            Lighting::default()
        };
        let (table, background) = if self.backgrounds {
            let table = projected(rng, &[], (0.05, 0.6));
            let pixels = random_pattern(rng, width as usize, height as usize);
            (table, Some(pixels.iter().map(|c| to_u8(*c)).collect()))
        } else {
            (Material::Uniform(TABLE_COLOUR), None)
        };
        Look {
            lighting,
            table,
            background,
            camera: self.camera.then(|| random_camera(rng)),
        }
    }

    /// The random surface of a distractor or occluder: one time in three each a flat colour,
    /// a procedural texture or one of `borrowed` (the objects' own textures; a procedural one
    /// when there are none).
    pub(crate) fn draw_surface<R: Rng>(rng: &mut R, borrowed: &[ImageTexture]) -> Material {
        if rng.random_range(0..3u8) == 0 {
            return Material::Uniform(std::array::from_fn(|_| rng.random::<f32>()));
        }
        let borrow = rng.random::<bool>();
        projected(rng, if borrow { borrowed } else { &[] }, (0.03, 0.2))
    }
}

/// The table's colour in the plain look.
pub(crate) const TABLE_COLOUR: [f32; 3] = [0.55, 0.5, 0.45];

/// What a frame looks like beyond its objects' own surfaces.
pub(crate) struct Look {
    pub lighting: Lighting,
    pub table: Material,
    /// The image behind everything, row-major (black where none).
    pub background: Option<Vec<[u8; 3]>>,
    pub camera: Option<ImageChain>,
}

fn to_u8(c: [f32; 3]) -> [u8; 3] {
    c.map(|v| (v * 255.0).round().clamp(0.0, 255.0) as u8)
}

/// One of `borrowed` or a 64² procedural pattern, repeated every `tile` metres (drawn in the
/// range, log-uniformly).
fn projected<R: Rng>(rng: &mut R, borrowed: &[ImageTexture], tile: (f32, f32)) -> Material {
    let texture = if borrowed.is_empty() {
        ImageTexture::new(64, 64, random_pattern(rng, 64, 64))
            .expect("a 64² pattern in [0, 1] is a valid texture")
    } else {
        borrowed[rng.random_range(0..borrowed.len())].clone()
    };
    let tile = tile.0 * (tile.1 / tile.0).powf(rng.random::<f32>());
    Material::Projected { texture, tile }
}

/// A light from anywhere on the camera's side (camera frame: `z < 0` points back at it), at
/// least 10° above the image plane; ambient 0.1–0.6, diffuse 0.3–1.0, a tint of up to 30% per
/// channel, and half the time a highlight of strength up to 0.6 and exponent 4–64.
fn random_lighting<R: Rng>(rng: &mut R) -> Lighting {
    let towards_light = loop {
        let v = Vector3::new(
            rng.random::<f64>() * 2.0 - 1.0,
            rng.random::<f64>() * 2.0 - 1.0,
            -rng.random::<f64>(),
        );
        let norm = v.norm();
        if norm > 1e-3 && norm <= 1.0 && -v.z / norm > 10f64.to_radians().sin() {
            break v / norm;
        }
    };
    let specular = if rng.random::<bool>() {
        0.6 * rng.random::<f32>()
    } else {
        0.0
    };
    Lighting {
        towards_light,
        ambient: 0.1 + 0.5 * rng.random::<f32>(),
        diffuse: 0.3 + 0.7 * rng.random::<f32>(),
        colour: std::array::from_fn(|_| 1.0 - 0.3 * rng.random::<f32>()),
        specular,
        shininess: 4.0 * 16f32.powf(rng.random::<f32>()),
        background: [0, 0, 0],
    }
}

/// A colour camera: blur σ 0–1.2 px, exposure 0.6–1.6 (log-uniform), white-balance gains
/// 0.85–1.15, shot noise up to 0.003 per unit of signal and read noise up to 1% of full scale
/// (consumer sensors' range in Foi et al. 2008), tone exponent 0.8–1.25, JPEG quality 30–95.
fn random_camera<R: Rng>(rng: &mut R) -> ImageChain {
    ImageChain {
        blur_sigma: 1.2 * rng.random::<f32>(),
        exposure: 0.6 * (1.6f32 / 0.6).powf(rng.random::<f32>()),
        white_balance: std::array::from_fn(|_| 0.85 + 0.3 * rng.random::<f32>()),
        shot_noise: 0.003 * rng.random::<f32>(),
        read_noise: 0.01 * rng.random::<f32>(),
        gamma: 0.8 * (1.25f32 / 0.8).powf(rng.random::<f32>()),
        jpeg_quality: Some(rng.random_range(30..=95)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn parts_parse_from_names_and_back() {
        assert_eq!(Randomization::parse("all").unwrap(), Randomization::ALL);
        assert_eq!(Randomization::parse("none").unwrap(), Randomization::NONE);
        let some = Randomization::parse("camera, lights").unwrap();
        assert_eq!(some.names(), ["lights", "camera"]);
        assert_eq!(Randomization::ALL.names(), PARTS);
        let error = Randomization::parse("lights,fog").unwrap_err().to_string();
        assert!(
            error.contains("randomize") && error.contains("fog"),
            "{error}"
        );
    }

    #[test]
    fn parts_that_are_off_draw_nothing_and_keep_the_plain_look() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
        let before = rng.clone().random::<u64>();
        let look = Randomization::NONE.draw_look(&mut rng, 8, 6);
        assert_eq!(rng.random::<u64>(), before, "no number drawn");
        assert_eq!(look.lighting, Lighting::default());
        assert_eq!(look.table, Material::Uniform(TABLE_COLOUR));
        assert!(look.background.is_none() && look.camera.is_none());
    }

    proptest::proptest! {
        /// Random lights come from the camera's side, at least 10° off the image plane, with
        /// strengths and tints in their ranges; cameras and backgrounds are valid.
        #[test]
        fn random_looks_stay_in_their_ranges(seed in proptest::prelude::any::<u64>()) {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let look = Randomization::ALL.draw_look(&mut rng, 8, 6);
            let light = look.lighting;
            proptest::prop_assert!((light.towards_light.norm() - 1.0).abs() < 1e-9);
            proptest::prop_assert!(-light.towards_light.z > 10f64.to_radians().sin() - 1e-12);
            proptest::prop_assert!((0.1..=0.6).contains(&light.ambient));
            proptest::prop_assert!((0.3..=1.0).contains(&light.diffuse));
            proptest::prop_assert!(light.colour.iter().all(|c| (0.7..=1.0).contains(c)));
            proptest::prop_assert!((0.0..=0.6).contains(&light.specular));
            proptest::prop_assert!((4.0..=64.0 + 1e-3).contains(&light.shininess));
            proptest::prop_assert_eq!(look.background.map(|b| b.len()), Some(48));
            let camera = look.camera.unwrap();
            proptest::prop_assert!(camera.jpeg_quality.is_some_and(|q| (30..=95).contains(&q)));
            let rgb = vec![[128u8; 3]; 48];
            proptest::prop_assert!(camera.apply(&rgb, 8, 6, seed).is_ok());
        }
    }

    #[test]
    fn distractor_surfaces_mix_flat_procedural_and_borrowed_textures() {
        let own = ImageTexture::new(1, 1, vec![[0.0, 1.0, 0.0]]).unwrap();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        let (mut flat, mut borrowed, mut procedural) = (0, 0, 0);
        for _ in 0..300 {
            match Randomization::draw_surface(&mut rng, std::slice::from_ref(&own)) {
                Material::Uniform(_) => flat += 1,
                Material::Projected { texture, tile } => {
                    assert!((0.03..=0.2).contains(&tile), "{tile}");
                    if texture == own {
                        borrowed += 1
                    } else {
                        procedural += 1
                    }
                }
                other => panic!("{other:?}"),
            }
        }
        // A third each: 100 expected (binomial sd 8.2).
        for count in [flat, borrowed, procedural] {
            assert!(
                (70..=130).contains(&count),
                "{flat} {borrowed} {procedural}"
            );
        }
    }
}
