//! CPU kernels that give the same numbers on every x86-64 machine with AVX2.
//!
//! libtorch chooses its CPU kernels per machine: ATen's vectorised loops, oneDNN's
//! convolutions and MKL's matrix products each take the widest instruction set the CPU has
//! (AVX-512, AMX, …). Each sums in its own order, so a model trained on one CPU differs in the
//! last bits from the same run on another, and training amplifies those bits into different
//! models (the quick pipeline's Recall MAAD moved by several degrees between two 2-core
//! machines). Measured on the quick preset's small CNN (3 epochs of 10 steps, one seed, this
//! machine an AVX-512 Xeon): each of the three libraries alone, set to AVX2, changed the
//! trained weights; with all three set, one and two libtorch threads gave bit-identical
//! checkpoints and evaluations, and the training step was no slower.
//!
//! A program sets these variables in its environment before libtorch starts (they are read
//! once, at the first kernel call): the `ipdf` binary re-executes itself with the missing
//! ones. Values already in the environment are left alone, so `ATEN_CPU_CAPABILITY=avx512`
//! still chooses the wider kernels.
//!
//! ```
//! use ipdf_model::REPRODUCIBLE_CPU_KERNELS;
//!
//! // What the `ipdf` binary adds where the environment does not say: AVX2 in all three.
//! assert_eq!(
//!     REPRODUCIBLE_CPU_KERNELS,
//!     [("ATEN_CPU_CAPABILITY", "avx2"), ("ONEDNN_MAX_CPU_ISA", "AVX2"), ("MKL_CBWR", "AVX2,STRICT")]
//! );
//! ```

/// The environment that pins libtorch's CPU kernels to AVX2 code paths:
/// - `ATEN_CPU_CAPABILITY=avx2`: ATen's vectorised element-wise and reduction loops;
/// - `ONEDNN_MAX_CPU_ISA=AVX2`: oneDNN's convolutions and pooling (no AVX-512 or AMX);
/// - `MKL_CBWR=AVX2,STRICT`: MKL's conditional numerical reproducibility, the AVX2 branch,
///   strict (the same results whatever the number of threads).
pub const REPRODUCIBLE_CPU_KERNELS: [(&str, &str); 3] = [
    ("ATEN_CPU_CAPABILITY", "avx2"),
    ("ONEDNN_MAX_CPU_ISA", "AVX2"),
    ("MKL_CBWR", "AVX2,STRICT"),
];

/// The settings of [`REPRODUCIBLE_CPU_KERNELS`] that this process's environment lacks.
pub fn missing_kernel_settings() -> Vec<(&'static str, &'static str)> {
    missing_from(|name| std::env::var_os(name).is_some())
}

/// The settings of [`REPRODUCIBLE_CPU_KERNELS`] whose variable `is_set` says is unset.
fn missing_from(is_set: impl Fn(&str) -> bool) -> Vec<(&'static str, &'static str)> {
    REPRODUCIBLE_CPU_KERNELS
        .into_iter()
        .filter(|(name, _)| !is_set(name))
        .collect()
}

/// The kernel settings in effect: each variable of [`REPRODUCIBLE_CPU_KERNELS`] and its value
/// in this process's environment (`None`: unset, libtorch picks per CPU). For reports.
pub fn kernel_settings() -> Vec<(&'static str, Option<String>)> {
    REPRODUCIBLE_CPU_KERNELS
        .into_iter()
        .map(|(name, _)| (name, std::env::var(name).ok()))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_the_unset_variables_are_missing() {
        assert_eq!(missing_from(|_| false), REPRODUCIBLE_CPU_KERNELS);
        assert!(missing_from(|_| true).is_empty());
        // A variable the user set (say to wider kernels) is left alone; the others are added.
        let missing = missing_from(|name| name == "ATEN_CPU_CAPABILITY");
        assert_eq!(
            missing,
            [("ONEDNN_MAX_CPU_ISA", "AVX2"), ("MKL_CBWR", "AVX2,STRICT")]
        );
    }
}
