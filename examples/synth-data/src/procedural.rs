//! Procedural images for randomised scenes (the random textures of Tobin et al. 2017): a flat
//! colour, a linear gradient, fractal value noise, random discs and rectangles, or stripes,
//! each in random colours.
use rand::{Rng, RngExt};

/// A row-major `width × height` image (linear RGB in `[0, 1]`, top row first) of one of the
/// five kinds, drawn with `rng`.
pub(crate) fn random_pattern<R: Rng>(rng: &mut R, width: usize, height: usize) -> Vec<[f32; 3]> {
    let (a, b) = (random_colour(rng), random_colour(rng));
    let at = |x: usize, y: usize| [x as f32 / width as f32, y as f32 / height as f32];
    let image = |f: &dyn Fn([f32; 2]) -> [f32; 3]| -> Vec<[f32; 3]> {
        (0..width * height)
            .map(|i| f(at(i % width, i / width)))
            .collect()
    };
    match rng.random_range(0..5u8) {
        0 => vec![a; width * height],
        1 => {
            let angle = rng.random::<f32>() * std::f32::consts::TAU;
            let (c, s) = (angle.cos(), angle.sin());
            image(&|[x, y]| mix(a, b, ((x - 0.5) * c + (y - 0.5) * s + 0.71) / 1.42))
        }
        2 => {
            let cells = 2 + rng.random_range(0..6usize);
            let noise = ValueNoise::new(rng, cells, 4);
            image(&|p| mix(a, b, noise.at(p)))
        }
        3 => shapes(rng, a, width, height),
        _ => {
            let angle = rng.random::<f32>() * std::f32::consts::TAU;
            let frequency = 2.0 + 18.0 * rng.random::<f32>();
            let (c, s) = (angle.cos(), angle.sin());
            let sharp = rng.random::<bool>();
            image(&|[x, y]| {
                let wave = (std::f32::consts::TAU * frequency * (x * c + y * s)).sin();
                let t = if sharp {
                    f32::from(wave > 0.0)
                } else {
                    0.5 + 0.5 * wave
                };
                mix(a, b, t)
            })
        }
    }
}

/// A colour uniform in the RGB cube.
fn random_colour<R: Rng>(rng: &mut R) -> [f32; 3] {
    std::array::from_fn(|_| rng.random::<f32>())
}

fn mix(a: [f32; 3], b: [f32; 3], t: f32) -> [f32; 3] {
    let t = t.clamp(0.0, 1.0);
    std::array::from_fn(|k| a[k] + (b[k] - a[k]) * t)
}

/// Octaves of random values on ever finer lattices, smoothly interpolated, summed with halving
/// weights: values in `[0, 1]`.
struct ValueNoise {
    /// Per octave: lattice cells across, and `(cells + 1)²` values.
    octaves: Vec<(usize, Vec<f32>)>,
}

impl ValueNoise {
    fn new<R: Rng>(rng: &mut R, cells: usize, octaves: usize) -> Self {
        let octaves = (0..octaves)
            .map(|o| {
                let n = cells << o;
                (n, (0..(n + 1) * (n + 1)).map(|_| rng.random()).collect())
            })
            .collect();
        Self { octaves }
    }

    fn at(&self, [x, y]: [f32; 2]) -> f32 {
        let (mut total, mut weight, mut sum) = (0.0, 1.0, 0.0);
        for (n, values) in &self.octaves {
            let (gx, gy) = (x * *n as f32, y * *n as f32);
            let (i, j) = ((gx as usize).min(n - 1), (gy as usize).min(n - 1));
            let smooth = |t: f32| t * t * (3.0 - 2.0 * t);
            let (fx, fy) = (smooth(gx - i as f32), smooth(gy - j as f32));
            let v = |i: usize, j: usize| values[j * (n + 1) + i];
            let top = v(i, j) + (v(i + 1, j) - v(i, j)) * fx;
            let bottom = v(i, j + 1) + (v(i + 1, j + 1) - v(i, j + 1)) * fx;
            total += weight * (top + (bottom - top) * fy);
            sum += weight;
            weight *= 0.5;
        }
        total / sum
    }
}

/// `base` under 5–30 discs and rectangles of random colours, places and sizes.
fn shapes<R: Rng>(rng: &mut R, base: [f32; 3], width: usize, height: usize) -> Vec<[f32; 3]> {
    let mut out = vec![base; width * height];
    let size = width.max(height) as f32;
    for _ in 0..rng.random_range(5..=30) {
        let colour = random_colour(rng);
        let (cx, cy) = (
            rng.random::<f32>() * width as f32,
            rng.random::<f32>() * height as f32,
        );
        let r = size * (0.02 + 0.2 * rng.random::<f32>());
        let disc = rng.random::<bool>();
        let (x0, x1) = ((cx - r).max(0.0) as usize, ((cx + r) as usize).min(width));
        let (y0, y1) = ((cy - r).max(0.0) as usize, ((cy + r) as usize).min(height));
        for y in y0..y1 {
            for x in x0..x1 {
                let (dx, dy) = (x as f32 + 0.5 - cx, y as f32 + 0.5 - cy);
                if !disc || dx * dx + dy * dy <= r * r {
                    out[y * width + x] = colour;
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    proptest::proptest! {
        /// Every pattern has the size asked for and colours in `[0, 1]`, and the same seed
        /// draws the same pattern.
        #[test]
        fn patterns_are_in_range_and_reproducible(seed in 0u64..10_000, w in 1usize..40, h in 1usize..40) {
            let draw = || random_pattern(&mut rand_chacha::ChaCha8Rng::seed_from_u64(seed), w, h);
            let image = draw();
            proptest::prop_assert_eq!(image.len(), w * h);
            proptest::prop_assert!(image.iter().flatten().all(|c| (0.0..=1.0).contains(c)));
            proptest::prop_assert_eq!(image, draw());
        }

        /// Value noise interpolates its lattice: it stays within the range of its values and
        /// equals the weighted sum of the octaves' lattice values at the coarsest lattice's
        /// points.
        #[test]
        fn value_noise_interpolates_its_lattice(seed in 0u64..10_000, i in 0usize..=3, j in 0usize..=3) {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let noise = ValueNoise::new(&mut rng, 3, 3);
            let p = [i.min(3) as f32 / 3.0, j.min(3) as f32 / 3.0];
            let (mut expected, mut weight, mut sum) = (0.0f32, 1.0f32, 0.0f32);
            for (n, values) in &noise.octaves {
                let (a, b) = (i * n / 3, j * n / 3);
                expected += weight * values[b * (n + 1) + a];
                sum += weight;
                weight *= 0.5;
            }
            let v = noise.at(p);
            proptest::prop_assert!((v - expected / sum).abs() < 1e-5, "{} {}", v, expected / sum);
            proptest::prop_assert!((0.0..=1.0).contains(&v));
        }
    }

    #[test]
    fn the_five_kinds_all_occur_and_differ() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        let mut distinct_colours = std::collections::BTreeSet::new();
        let mut flat = 0;
        for _ in 0..200 {
            let image = random_pattern(&mut rng, 16, 16);
            let colours: std::collections::BTreeSet<[u32; 3]> =
                image.iter().map(|c| c.map(f32::to_bits)).collect();
            flat += usize::from(colours.len() == 1);
            distinct_colours.insert(colours.len().min(50));
        }
        // One kind in five is flat: 40 of 200 expected (binomial sd 5.7).
        assert!((20..=60).contains(&flat), "{flat} flat");
        assert!(distinct_colours.len() > 5, "{distinct_colours:?}");
    }
}
