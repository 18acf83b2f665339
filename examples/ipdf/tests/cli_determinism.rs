//! Determinism across thread counts through the real binary: `ipdf` pins libtorch's CPU
//! kernels (`ipdf_model::REPRODUCIBLE_CPU_KERNELS`), with which the small CNN trains to the same
//! bits on one thread as on two (the deep small CNN to the same bits on the same threads), and
//! labelling never depended on threads.
use crate::common;

use common::{BRIEF_TRAINING, ipdf_json, s, synth, train_args};

#[test]
fn training_and_labelling_give_the_same_bits_on_one_and_two_threads() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    synth(&data, "box", 6, &[]);
    let mut labels = Vec::new();
    for threads in ["1", "2"] {
        let copy = dir.path().join(format!("data_{threads}"));
        common::copy_dir(&data, &copy);
        ipdf_json(&["label", "--dataset", s(&copy), "--threads", threads]);
        labels.push(std::fs::read(copy.join("train/000000/scene_pseudo_gt.json")).unwrap());
    }
    assert_eq!(labels[0], labels[1], "labels on 1 and 2 threads");
    let data = dir.path().join("data_1");
    // The demo's small CNN gives the same bits on one thread and on two. The quick mesh
    // preset's deep one, whose stride-1 convolutions sum their gradients per thread as
    // ResNet-18's do, gives the same bits for the same thread count.
    for (encoder, thread_counts) in [("small-cnn", ["1", "2"]), ("small-cnn-deep", ["2", "2"])] {
        let mut weights = Vec::new();
        for (k, threads) in thread_counts.into_iter().enumerate() {
            let run = dir.path().join(format!("run_{encoder}_{k}"));
            let mut args = train_args(&data, "pseudo", &["--out", s(&run), "--val-split", "none"]);
            args.extend([
                "--encoder",
                encoder,
                "--input-size",
                "32",
                "--head",
                "32,32",
            ]);
            args.extend(["--query-level", "1"]);
            args.extend(BRIEF_TRAINING);
            args.extend(["--learning-rate", "4e-3", "--threads", threads]);
            let result = ipdf_json(&args);
            let checkpoint = std::fs::read_dir(&run)
                .unwrap()
                .map(|entry| entry.unwrap().path())
                .find(|path| {
                    let name = path.file_name().unwrap().to_string_lossy();
                    name.starts_with("model-") && name.ends_with(".safetensors")
                })
                .unwrap();
            weights.push((std::fs::read(checkpoint).unwrap(), result["loss"].clone()));
        }
        assert_eq!(weights[0].1, weights[1].1, "{encoder}: final loss");
        assert!(
            weights[0].0 == weights[1].0,
            "{encoder}: the weights differ between {thread_counts:?} threads"
        );
    }
}
