//! Rotation queries as network input: the flattened rotation matrix and its positional encoding.
use nalgebra::UnitQuaternion;
use tch::{Device, Tensor};

/// Rotations as a `[N, 9]` float tensor of row-major 3×3 matrices on `device`.
pub fn rotations_to_tensor(rotations: &[UnitQuaternion<f64>], device: Device) -> Tensor {
    let mut values = Vec::with_capacity(rotations.len() * 9);
    for rotation in rotations {
        let m = rotation.to_rotation_matrix().into_inner();
        for row in 0..3 {
            for col in 0..3 {
                values.push(m[(row, col)] as f32);
            }
        }
    }
    Tensor::from_slice(&values)
        .reshape([rotations.len() as i64, 9])
        .to_device(device)
}

/// The length of [`encode_rotations`]' output: `18 · components`, or 9 (the raw matrix) for
/// `components = 0`.
pub const fn encoded_len(components: i64) -> i64 {
    if components == 0 { 9 } else { 18 * components }
}

/// Positional encoding of flattened rotation matrices `[…, 9]` (Murphy et al. 2021, §3.4):
/// `[sin(2⁰r), cos(2⁰r), …, sin(2^(F−1)r), cos(2^(F−1)r)]` for `F = components`, `[…, 18F]`;
/// the matrix itself for `F = 0`.
pub fn encode_rotations(rotations: &Tensor, components: i64) -> Tensor {
    encode_fourier(rotations, components)
}

/// The positional encoding of [`encode_rotations`] for any trailing length `D`: `[…, 2DF]`, or
/// the values themselves for `F = 0`.
pub(crate) fn encode_fourier(values: &Tensor, components: i64) -> Tensor {
    if components == 0 {
        return values.shallow_clone();
    }
    let parts: Vec<Tensor> = (0..components)
        .flat_map(|k| {
            let scaled = values * f64::powi(2.0, k as i32);
            [scaled.sin(), scaled.cos()]
        })
        .collect();
    Tensor::cat(&parts, -1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn encoding_has_the_documented_layout() {
        let r = Tensor::from_slice(&[0.5f32; 9]).reshape([1, 9]);
        let encoded = encode_rotations(&r, 2);
        assert_eq!(encoded.size(), [1, encoded_len(2)]);
        let values = Vec::<f32>::try_from(encoded.reshape([-1])).unwrap();
        assert!((values[0] - 0.5f32.sin()).abs() < 1e-6);
        assert!((values[9] - 0.5f32.cos()).abs() < 1e-6);
        assert!((values[18] - 1.0f32.sin()).abs() < 1e-6);
        assert!((values[27] - 1.0f32.cos()).abs() < 1e-6);
        assert_eq!(encode_rotations(&r, 0).size(), [1, 9]);
    }

    #[test]
    fn rotation_tensor_is_row_major() {
        let q = UnitQuaternion::from_euler_angles(0.3, -0.2, 1.1);
        let t = rotations_to_tensor(&[q], Device::Cpu);
        let values = Vec::<f32>::try_from(t.reshape([-1])).unwrap();
        let m = q.to_rotation_matrix();
        assert!((values[1] as f64 - m[(0, 1)]).abs() < 1e-6);
        assert!((values[3] as f64 - m[(1, 0)]).abs() < 1e-6);
    }
}
