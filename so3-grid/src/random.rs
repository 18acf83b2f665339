//! Uniform (Haar) random rotations, reproducible from a seed at any thread count.
use nalgebra::{Quaternion, UnitQuaternion};
use rand::{Rng, RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

/// Rotations per independently seeded stream in [`random_rotations`].
const STREAM_LEN: usize = 4096;

/// One uniform random rotation from `rng` (Shoemake 1992, "Uniform random rotations"): three
/// uniform numbers map to a uniformly distributed unit quaternion.
pub fn random_rotation<R: Rng + ?Sized>(rng: &mut R) -> UnitQuaternion<f64> {
    let (u1, u2, u3): (f64, f64, f64) = (rng.random(), rng.random(), rng.random());
    let (a, b) = ((1.0 - u1).sqrt(), u1.sqrt());
    let (s2, c2) = (std::f64::consts::TAU * u2).sin_cos();
    let (s3, c3) = (std::f64::consts::TAU * u3).sin_cos();
    UnitQuaternion::new_normalize(Quaternion::new(b * c3, a * s2, a * c2, b * s3))
}

/// `count` uniform random rotations from `seed`, generated in parallel on the current rayon
/// pool. The result depends only on `(count, seed)`: block `i` of 4096 rotations is drawn from
/// ChaCha8 stream `i` of the seed.
pub fn random_rotations(count: usize, seed: u64) -> Vec<UnitQuaternion<f64>> {
    let mut out = vec![UnitQuaternion::identity(); count];
    out.par_chunks_mut(STREAM_LEN)
        .enumerate()
        .for_each(|(stream, chunk)| {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            rng.set_stream(stream as u64);
            chunk
                .iter_mut()
                .for_each(|q| *q = random_rotation(&mut rng));
        });
    out
}
