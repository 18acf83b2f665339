//! Implicit-PDF (Murphy et al., 2021) on libtorch through `tch`: an image-conditioned,
//! unnormalised log-density F(R, I) over SO(3). The model itself is filled by its own issue;
//! this crate currently pins and checks the libtorch link.
//!
//! ```
//! let device = ipdf_model::default_device();
//! let x = tch::Tensor::from_slice(&[1.0f32, 2.0, 3.0]).to_device(device);
//! assert_eq!(f32::try_from(x.sum(tch::Kind::Float)).unwrap(), 6.0);
//! ```

/// The device new tensors and models should live on: the first CUDA device when libtorch has
/// CUDA and one is visible, the CPU otherwise.
pub fn default_device() -> tch::Device {
    tch::Device::cuda_if_available()
}

#[cfg(test)]
mod tests {
    use tch::{Kind, Tensor};

    #[test]
    fn libtorch_runs_a_matrix_product() {
        let a = Tensor::from_slice(&[1.0f32, 2.0, 3.0, 4.0]).reshape([2, 2]);
        let b = a.matmul(&a.transpose(0, 1)).reshape([-1]);
        assert_eq!(
            Vec::<f32>::try_from(&b).unwrap(),
            vec![5.0, 11.0, 11.0, 25.0]
        );
        assert_eq!(b.kind(), Kind::Float);
    }
}
