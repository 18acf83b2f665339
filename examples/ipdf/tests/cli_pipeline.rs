//! `ipdf train`, `eval`, `predict`, `viz` and `pipeline` through the real binary: a miniature
//! pipeline (a few dozen frames, tens of training steps) whose every artefact exists and
//! parses with plausible values, and bad inputs that fail with one line.
use crate::common;

use std::path::Path;

use common::{
    assert_fails, ipdf_json, predict_args, read_json, s, strs, synth, train_args, viz_args,
};

fn png_size(path: &Path) -> (u32, u32) {
    image::image_dimensions(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn a_miniature_pipeline_writes_every_artefact() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let words = [
        "pipeline",
        "--preset",
        "quick",
        "--out",
        s(&out),
        "--frames",
        "6",
        "--val-frames",
        "2",
        "--texture-frames",
        "2",
        "--epochs",
        "2",
        "--steps-per-epoch",
        "4",
    ];
    let result = ipdf_json(&words);
    let report = read_json(&out.join("report.json"));
    assert_eq!(result["report_json"], s(&out.join("report.json")));
    let markdown = std::fs::read_to_string(out.join("report.md")).unwrap();
    for object in ["can", "box", "bowl"] {
        for variant in ["uniform", "texture"] {
            let entry = &report["labels"][object][variant];
            let maad = entry["label_maad_deg"].as_f64().unwrap();
            let coverage = entry["coverage"].as_f64().unwrap();
            assert!(
                (0.0..5.0).contains(&maad) && (0.5..=1.0).contains(&coverage),
                "{object} {variant}: {entry}"
            );
        }
        for labels in ["single", "analytical", "pseudo"] {
            let scores = &report["models"][labels][object];
            let llh = scores["llh"].as_f64().unwrap();
            let maad = scores["maad_deg"].as_f64().unwrap();
            let recall = scores["recall_maad_deg"].as_f64().unwrap();
            // Format checks, not accuracy: two epochs of a few steps learn too little for a
            // bound a correct model must meet (the demo's figures: docs/results.md). LLH near
            // the uniform density (−2.29), angles within [0°, 180°].
            assert!(
                llh.is_finite() && llh > -20.0 && llh < 10.0,
                "{labels} {object}: {scores}"
            );
            assert!(
                (0.0..=180.0).contains(&maad) && (0.0..=180.0).contains(&recall),
                "{scores}"
            );
            let run = out.join("models").join(object).join(labels);
            let log = std::fs::read_to_string(run.join("train_log.csv")).unwrap();
            assert_eq!(log.lines().count(), 3, "{log}");
            assert_eq!(read_json(&run.join("run.json"))["object"], object);
            assert!(run.join("checkpoint.json").exists());
            let stem = format!("{object}_{labels}");
            assert_eq!(
                png_size(&out.join("figures").join(format!("{stem}.png"))),
                (1180, 480)
            );
            assert_eq!(
                png_size(&out.join("figures").join(format!("{stem}_curves.png"))),
                (1200, 480)
            );
            assert!(markdown.contains(&format!("figures/{stem}.png")));
            // Analytical and Pseudo runs are 6D poses: a translation model beside the rotation
            // one, its scores and its figure. Single's would be Analytical's (same translations).
            let translation = &scores["translation"];
            let figure = out.join("figures").join(format!("{stem}_translation.png"));
            if labels == "single" {
                assert!(translation.is_null() && !figure.exists(), "{scores}");
                continue;
            }
            // Format checks, as above: an error is a finite distance, the joint LLH the sum.
            let error = translation["median_error_mm"].as_f64().unwrap();
            let llh = translation["llh"].as_f64().unwrap();
            assert!(
                error >= 0.0 && error.is_finite() && llh.is_finite(),
                "{translation}"
            );
            let joint = scores["pose"]["joint_llh"].as_f64().unwrap();
            assert!((joint - llh - scores["llh"].as_f64().unwrap()).abs() < 1e-9);
            let auc = scores["pose"]["add_s_auc"].as_f64().unwrap();
            assert!((0.0..=1.0).contains(&auc), "{scores}");
            let log = std::fs::read_to_string(run.join("translation/train_log.csv")).unwrap();
            assert_eq!(log.lines().count(), 3, "{log}");
            assert_eq!(png_size(&figure), (1000, 520));
            assert!(markdown.contains(&format!("figures/{stem}_translation.png")));
        }
    }
    assert!(markdown.contains("## Translation and 6D pose"));
    // The pseudo-label errors of both datasets, one panel each.
    assert_eq!(png_size(&out.join("figures/label_errors.png")), (1120, 460));
    assert!(markdown.contains("figures/label_errors.png"));
    for stage in ["synth", "label", "train", "eval", "figures"] {
        assert!(report["timing_s"][stage].as_f64().is_some(), "{stage}");
    }
    // The libtorch kernels the binary pinned, recorded (see docs/method.md, "Determinism").
    for (name, value) in ipdf_model::REPRODUCIBLE_CPU_KERNELS {
        assert_eq!(report["cpu_kernels"][name], value, "{name}");
    }
    // The stage times are the run folder's, kept in timing.json as each stage ends.
    assert_eq!(read_json(&out.join("timing.json")), report["timing_s"]);
    // A rerun skips every stage: nothing is retrained, and what it spends is added to the
    // earlier invocation's times instead of replacing them.
    let checkpoint = read_json(&out.join("models/can/pseudo/checkpoint.json"));
    ipdf_json(&words);
    assert_eq!(
        read_json(&out.join("models/can/pseudo/checkpoint.json")),
        checkpoint
    );
    let rerun = read_json(&out.join("report.json"));
    assert_eq!(read_json(&out.join("timing.json")), rerun["timing_s"]);
    for stage in ["synth", "label", "train", "eval", "figures"] {
        let (first, total) = (&report["timing_s"][stage], &rerun["timing_s"][stage]);
        assert!(
            total.as_f64() >= first.as_f64(),
            "{stage}: {first} then {total}"
        );
    }
    // A damaged record is refused, naming it; the folder is left for the user to mend.
    let timing = out.join("timing.json");
    let kept = std::fs::read(&timing).unwrap();
    std::fs::write(&timing, "{\"synth\": ").unwrap();
    assert_fails(&words, "timing.json");
    std::fs::write(&timing, kept).unwrap();

    // The single commands on the run's artefacts.
    let run = out.join("models/box/pseudo");
    let scene = out.join("data/uniform/val/000001");
    let (rgb, mask) = (
        scene.join("rgb/000000.png"),
        scene.join("mask_visib/000000_000000.png"),
    );
    let prediction = dir.path().join("prediction.npy");
    let predicted = ipdf_json(&predict_args(
        &run,
        &rgb,
        &mask,
        &prediction,
        &["--level", "2"],
    ));
    assert_eq!(predicted["cells"], 4608);
    assert_eq!(read_json(&prediction.with_extension("json"))["level"], 2);
    let bytes = std::fs::read(&prediction).unwrap();
    assert!(bytes.starts_with(b"\x93NUMPY") && bytes.len() > 4 * 4608);
    let scores = ipdf_json(&["eval", "--checkpoint", s(&run), "--level", "2"]);
    assert_eq!(
        (scores["object"].as_str(), scores["images"].as_u64()),
        (Some("box"), Some(2))
    );
    // Level 3 refined from level 2 within its budget, against every level-3 cell.
    let refined = ipdf_json(&["eval", "--checkpoint", s(&run), "--level", "3"]);
    let dense = ipdf_json(&["eval", "--checkpoint", s(&run), "--level", "3", "--dense"]);
    assert_eq!(refined["evaluation"], "hierarchical");
    assert!(
        refined["queries_per_image"].as_u64().unwrap() <= 9_472,
        "{refined}"
    );
    assert_eq!(
        (
            dense["evaluation"].as_str(),
            dense["queries_per_image"].as_u64()
        ),
        (Some("dense"), Some(36_864))
    );
    let gap = |key: &str| (refined[key].as_f64().unwrap() - dense[key].as_f64().unwrap()).abs();
    assert!(
        gap("llh") < 0.02 && gap("maad_deg") < 0.2,
        "{refined} {dense}"
    );
    assert_fails(
        &["eval", "--checkpoint", s(&run), "--level", "6", "--dense"],
        "--dense goes up to level 5",
    );
    assert_fails(
        &["eval", "--checkpoint", s(&run), "--level", "7"],
        "7 is not in 0..=6",
    );
    let figure = dir.path().join("viz.png");
    ipdf_json(&viz_args(&run, &figure, &["--scene", "1", "--image", "0"]));
    assert_eq!(png_size(&figure), (1180, 480));
    // With test-time views the distribution drawn is another one (the crop panel is the same).
    let viewed = dir.path().join("viz_views.png");
    let drawn = ["--scene", "1", "--image", "0", "--views", "8"];
    ipdf_json(&viz_args(&run, &viewed, &drawn));
    let pixels = |path: &Path| image::open(path).unwrap().to_rgb8().into_raw();
    assert_ne!(pixels(&figure), pixels(&viewed));
    assert_fails(
        &viz_args(
            &run,
            &viewed,
            &["--scene", "1", "--image", "0", "--views", "9"],
        ),
        "--views",
    );
    ipdf_json(&["viz", "--train-log", s(&run), "--out", s(&figure)]);
    assert_eq!(png_size(&figure), (1200, 480));

    // Bad inputs: one line each.
    let data = out.join("data/uniform");
    let x = dir.path().join("x");
    assert_fails(&train_args(&data, "pseudo", &["--out", s(&x)]), "obj_id");
    assert_fails(&train_args(&data, "guess", &["--out", s(&x)]), "guess");
    let vgg = ["--object", "can", "--encoder", "vgg", "--out", s(&x)];
    assert_fails(&train_args(&data, "single", &vgg), "vgg");
    let val = ["--object", "can", "--split", "val", "--out", s(&x)];
    assert_fails(
        &train_args(&out.join("data/texture"), "pseudo", &val),
        "val",
    );
    assert_fails(&["eval", "--checkpoint", s(dir.path())], "run.json");
    assert_fails(
        &["eval", "--checkpoint", s(&run), "--models-dir", "no_models"],
        "no_models",
    );
    let none = dir.path().join("none.png");
    assert_fails(
        &predict_args(&run, &rgb, &none, &prediction, &[]),
        "none.png",
    );
    assert_fails(&["viz", "--out", s(&figure)], "--train-log");
    assert_fails(
        &["pipeline", "--out", s(&x), "--translation-epochs", "0"],
        "--translation-epochs",
    );
    // Scene 0 shows the can: the box's model is not drawn on it.
    assert_fails(
        &viz_args(&run, &figure, &["--scene", "0", "--image", "0"]),
        "the model is for object 2",
    );
    let train = |flag: &str, value: &str| {
        let out = dir.path().join("refused");
        let args = ["--object", "box", "--out", s(&out), flag, value];
        train_args(&data, "single", &args)
            .iter()
            .map(|a| a.to_string())
            .collect::<Vec<_>>()
    };
    for (flag, value, expected) in [
        ("--input-size", "0", "input_size"),
        ("--batch-size", "0", "--batch-size"),
        ("--blur", "11", "--blur"),
        ("--learning-rate", "0", "schedule.peak"),
        ("--translation-learning-rate", "nan", "schedule.peak"),
    ] {
        let mut args = train(flag, value);
        if flag == "--translation-learning-rate" {
            args.extend(["--target", "translation"].map(String::from));
        }
        assert_fails(&strs(&args), expected);
        // Refused before the run folder is written to.
        assert!(!dir.path().join("refused").exists(), "{flag} {value}");
    }
    // Another run's folder is not silently continued with other data.
    let small_cnn = [
        "--object",
        "box",
        "--out",
        s(&run),
        "--encoder",
        "small-cnn",
    ];
    assert_fails(&train_args(&data, "single", &small_cnn), "other data");
}

#[test]
fn pseudo_training_without_labels_says_how_to_make_them() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    synth(&data, "box", 2, &[]);
    let run = dir.path().join("run");
    assert_fails(
        &train_args(&data, "pseudo", &["--out", s(&run)]),
        "ipdf label --dataset",
    );
}
