//! Reruns into existing output folders through the real binary: `ipdf synth` and `ipdf
//! pipeline` resume an identical run and refuse one whose options differ, naming the option;
//! plus the global flags' and `grid`'s argument checks.
use crate::common;

use common::{assert_fails, ipdf, ipdf_json, read_json, s, synth, synth_args};

#[test]
fn a_synth_rerun_with_other_options_is_refused_and_an_identical_one_resumes() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    let args = |frames: &'static str, extra: &[&'static str]| {
        let mut words = synth_args(&data, "can,box", frames, &[]);
        if !extra.contains(&"--frames-per-scene") {
            words.extend(["--frames-per-scene", "2"]);
        }
        words.extend_from_slice(extra);
        words
    };
    let first = ipdf_json(&args("2", &[]));
    assert_eq!(
        (&first["frames"], &first["rendered"]),
        (&4.into(), &4.into())
    );
    // An interrupted run: the box's scene lost its last file, so it is incomplete.
    let box_scene = data.join("train/000001");
    std::fs::remove_file(box_scene.join("scene_gt_info.json")).unwrap();
    let resumed = ipdf_json(&args("2", &[]));
    assert_eq!(
        (&resumed["frames"], &resumed["rendered"]),
        (&4.into(), &2.into())
    );
    assert!(box_scene.join("scene_gt_info.json").exists());
    let again = ipdf_json(&args("2", &[]));
    assert_eq!(again["rendered"], 0);
    // A damaged record of the options is refused, naming the file, and left as it was.
    let record = data.join("train/synth_options.json");
    let kept = std::fs::read(&record).unwrap();
    for damaged in ["{not json", "[1, 2]"] {
        std::fs::write(&record, damaged).unwrap();
        assert_fails(&args("2", &[]), "synth_options.json");
    }
    std::fs::write(&record, kept).unwrap();

    for (extra, option) in [
        (args("3", &[]), "frames"),
        (args("2", &["--frames-per-scene", "1"]), "frames_per_scene"),
        (args("2", &["--seed", "7"]), "seed"),
        (args("2", &["--distractors", "1"]), "distractors"),
        (args("2", &["--elevation", "20", "80"]), "elevation_deg"),
        (args("2", &["--off-centre", "1"]), "off_centre"),
        (args("2", &["--roll", "30"]), "roll_deg"),
        (args("2", &["--placement", "arranged"]), "placement"),
        (args("2", &["--randomize"]), "randomize"),
        (args("2", &["--randomize", "lights,camera"]), "randomize"),
    ] {
        assert_fails(&extra, option);
        assert_fails(&extra, "train/synth_options.json");
    }
    // Nothing was rendered by the refused runs: scenes 0 and 1 only.
    let scenes = std::fs::read_dir(data.join("train")).unwrap().count();
    assert_eq!(scenes, 3, "two scenes and synth_options.json");
    // An unknown part of the randomisation is refused, naming the option and the part.
    assert_fails(&args("2", &["--randomize", "lights,fog"]), "randomize");
    assert_fails(&args("2", &["--randomize", "lights,fog"]), "fog");
    // Another split is another set of options.
    let val = synth(&data, "can,box", 1, &["--split", "val", "--seed", "1"]);
    assert_eq!(val["rendered"], 2);
}

#[test]
fn synth_refuses_a_split_that_is_not_a_plain_folder_name() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("a/b");
    for split in ["../../escape", "/abs", "a/b", "..", ".", ""] {
        assert_fails(&synth_args(&data, "box", "1", &["--split", split]), "split");
    }
    assert!(!dir.path().join("escape").exists());
    assert!(!data.exists(), "nothing written");
}

#[test]
fn a_pipeline_rerun_with_other_settings_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    // A run folder as a pipeline run leaves it when it starts: its recorded settings.
    std::fs::create_dir_all(&out).unwrap();
    let settings = |frames: &'static str| {
        vec![
            "pipeline",
            "--out",
            s(&out),
            "--frames",
            frames,
            "--val-frames",
            "1",
            "--texture-frames",
            "1",
            "--epochs",
            "1",
            "--steps-per-epoch",
            "1",
        ]
    };
    // A refused run stops before the first stage; an accepted one records its settings first:
    // let one start with a file in the way of the synth stage, so it fails right after that.
    std::fs::write(out.join("data"), "in the way").unwrap();
    let started = ipdf(&settings("2"));
    assert!(!started.status.success());
    let config = read_json(&out.join("pipeline_config.json"));
    assert_eq!(config["frames_per_object"], 2);
    assert_eq!(config["epochs"], 1);
    // The quick preset's depth is a Kinect's.
    assert_eq!(config["sensor"], "kinect");
    assert_fails(&settings("5"), "frames_per_object (--frames)");
    let mut clean = settings("2");
    clean.push("--clean-depth");
    assert_fails(&clean, "sensor (--sensor or --clean-depth)");
    clean.extend(["--sensor", "kinect"]);
    assert_fails(&clean, "cannot be used with");
    // Another sensor is recorded as asked.
    let other = dir.path().join("other");
    std::fs::create_dir_all(other.join("data")).unwrap();
    std::fs::write(other.join("data/uniform"), "in the way").unwrap();
    let mut realsense = settings("2");
    realsense[2] = s(&other);
    realsense.extend(["--sensor", "realsense"]);
    assert!(!ipdf(&realsense).status.success());
    let config = read_json(&other.join("pipeline_config.json"));
    assert_eq!(config["sensor"], "realsense");
    let mut seeded = settings("2");
    seeded.extend(["--seed", "3"]);
    assert_fails(&seeded, "seed");
    let mut paper = settings("2");
    paper.extend(["--preset", "paper"]);
    assert_fails(&paper, "preset");
    // The identical rerun gets past the check (and fails at the same place as before).
    let again = ipdf(&settings("2"));
    let stderr = String::from_utf8_lossy(&again.stderr);
    assert!(!again.status.success());
    assert!(!stderr.contains("pipeline_config.json"), "{stderr}");
    // A recorded settings file that is not a JSON object is refused, naming it.
    std::fs::write(out.join("pipeline_config.json"), "[1, 2]").unwrap();
    assert_fails(&settings("2"), "pipeline_config.json");
}

#[test]
fn global_flags_and_grid_outputs_are_checked() {
    // No subcommand: the usage, not an error about the program.
    let out = ipdf(&[]);
    assert!(!out.status.success());
    let text = String::from_utf8_lossy(&out.stderr);
    assert!(text.contains("Usage: ipdf"), "{text}");
    assert!(text.contains("grid"), "{text}");

    let dir = tempfile::tempdir().unwrap();
    let npy = dir.path().join("g.npy");
    assert_fails(
        &[
            "grid",
            "--level",
            "0",
            "--out",
            s(&npy),
            "--threads",
            "100000",
        ],
        "--threads",
    );
    let summary = ipdf_json(&["grid", "--level", "0", "--out", s(&npy), "--threads", "2"]);
    assert_eq!(summary["count"], 72);
    for name in ["g.json", "g", "g.npy.tmp"] {
        let path = dir.path().join(name);
        assert_fails(&["grid", "--level", "0", "--out", s(&path)], ".npy");
        assert!(!path.exists(), "{name} written");
    }
}
