//! `ipdf pipeline --mesh` through the real binary: one scanned mesh of the real YCB-Video
//! fixture, in miniature (a few dozen renders, a few training steps), scored on the fixture's
//! real frames. The instances scored are counted from the fixture's own files; accuracy is not
//! checked (docs/results.md measures it at full size).
use crate::common;

use std::path::{Path, PathBuf};

use common::{ipdf, ipdf_in, ipdf_json, read_json, s};
use serde_json::{Value, json};

/// The fixture's folder, in the crate that owns it.
fn fixture() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../pseudo-label/tests/data/ycbv_real")
}

/// The mustard bottle: the fixture's one object seen in two scenes.
const OBJ_ID: u64 = 5;

/// `(scene, image)` of every instance of `obj_id` at least 10% visible, from the fixture's
/// `scene_gt.json` and `scene_gt_info.json`.
fn instances_of(root: &Path, obj_id: u64) -> Vec<(u64, u64)> {
    let mut found = Vec::new();
    for scene in ["000000", "000001", "000002"] {
        let folder = root.join("test").join(scene);
        let gt = read_json(&folder.join("scene_gt.json"));
        let info = read_json(&folder.join("scene_gt_info.json"));
        for (image, entries) in gt.as_object().unwrap() {
            for (k, entry) in entries.as_array().unwrap().iter().enumerate() {
                let visible = info[image][k]["visib_fract"].as_f64().unwrap();
                if entry["obj_id"] == obj_id && visible >= 0.1 {
                    found.push((scene.parse().unwrap(), image.parse().unwrap()));
                }
            }
        }
    }
    found.sort();
    found
}

/// The fixture's camera (its `cam_K`, 640 × 480, 0.1 mm depth units) as a camera file.
fn write_camera(path: &Path) {
    let camera = read_json(&fixture().join("test/000000/scene_camera.json"));
    let k = &camera["1"]["cam_K"];
    let file = json!({"fx": k[0], "fy": k[4], "cx": k[2], "cy": k[5], "width": 640,
                      "height": 480, "depth_scale": 0.1});
    std::fs::write(path, file.to_string()).unwrap();
}

/// Asserts that `ipdf args` fails, its last line on standard error containing `expected` (the
/// line before it, if any, is the mesh's repairs: this scan has two zero-area triangles).
fn assert_refused(args: &[&str], expected: &str) {
    let out = ipdf(args);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "ipdf {args:?} succeeded");
    let last = stderr.trim_end().lines().last().unwrap_or_default();
    assert!(last.contains(expected), "ipdf {args:?}: {stderr}");
    assert!(stderr.trim_end().lines().count() <= 2, "{stderr}");
}

/// A miniature run's sizes: a few dozen renders, a few training steps.
const MINIATURE: [&str; 8] = [
    "--frames",
    "24",
    "--val-frames",
    "4",
    "--epochs",
    "1",
    "--steps-per-epoch",
    "3",
];

/// A temporary folder holding the fixture's camera file, and the paths of a run in it.
struct Setup {
    dir: tempfile::TempDir,
    camera: PathBuf,
    out: PathBuf,
    mesh: PathBuf,
    root: PathBuf,
}

impl Setup {
    fn new() -> Self {
        let dir = tempfile::tempdir().unwrap();
        let (camera, out) = (dir.path().join("camera.json"), dir.path().join("run"));
        write_camera(&camera);
        let root = fixture();
        let mesh = root.join("models/obj_000005.ply");
        Self {
            dir,
            camera,
            out,
            mesh,
            root,
        }
    }

    /// `ipdf pipeline --mesh` of the fixture's mustard bottle with the camera file `camera`
    /// into the run folder, then `extra`.
    fn command<'a>(&'a self, camera: &'a Path, extra: &[&'a str]) -> Vec<&'a str> {
        let mut words = vec![
            "pipeline",
            "--mesh",
            s(&self.mesh),
            "--camera",
            s(camera),
            "--out",
            s(&self.out),
        ];
        words.extend(extra);
        words
    }

    /// The words of a miniature run with the camera file `camera`, then `extra`.
    fn words<'a>(&'a self, camera: &'a Path, extra: &[&'a str]) -> Vec<&'a str> {
        let mut words = self.command(camera, &MINIATURE);
        words.extend([
            "--rotation-members",
            "2",
            "--real",
            s(&self.root),
            "--obj-id",
            "5",
        ]);
        words.extend(extra);
        words
    }

    /// The words of a miniature run of efficientnet-lite0 from `weights` with `frozen` blocks
    /// frozen, then `extra`.
    fn pretrained_run<'a>(
        &'a self,
        weights: &'a Path,
        frozen: &'a str,
        extra: &[&'a str],
    ) -> Vec<&'a str> {
        let mut words = self.command(&self.camera, &MINIATURE);
        words.extend([
            "--encoder",
            "efficientnet-lite0",
            "--pretrained",
            s(weights),
        ]);
        words.extend(["--freeze-encoder", frozen]);
        words.extend(extra);
        words
    }

    /// The `pipeline_config.json` a mesh run with `extra` records. A run records its settings
    /// before its first stage: a file in the way of the renders stops it right after.
    fn recorded_config(&self, extra: &[&str]) -> Value {
        self.recorded_config_in(Path::new("."), extra)
    }

    /// [`Setup::recorded_config`] of a run started in the folder `dir`.
    fn recorded_config_in(&self, dir: &Path, extra: &[&str]) -> Value {
        std::fs::create_dir_all(&self.out).unwrap();
        std::fs::write(self.out.join("data"), "in the way").unwrap();
        std::fs::remove_file(self.out.join("pipeline_config.json")).ok();
        assert!(
            !ipdf_in(dir, &self.command(&self.camera, extra))
                .status
                .success()
        );
        read_json(&self.out.join("pipeline_config.json"))
    }
}

/// The repository's root, where `make setup` puts the ImageNet weights.
fn repository() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

#[test]
fn a_mesh_run_is_scored_on_the_real_frames() {
    let setup = Setup::new();
    let (out, root) = (&setup.out, &setup.root);
    ipdf_json(&setup.words(&setup.camera, &[]));

    let report = read_json(&out.join("report.json"));
    assert_eq!(report["object"], "obj_000005");
    assert_eq!(report["config"]["training_data"], "randomised renders");
    assert_eq!(report["config"]["frames_per_object"], 24);
    let parts = ["lights", "backgrounds", "textures", "camera"];
    assert_eq!(report["config"]["randomize"], json!(parts));
    assert_eq!(report["config"]["placement"], "arranged");
    // The rotation model learns in the line of sight's frame, and its checkpoint says so.
    assert_eq!(report["config"]["rotation_frame"], "line-of-sight");
    let checkpoint = read_json(&out.join("model/checkpoint.json"));
    assert_eq!(checkpoint["model"]["rotation_frame"], "line-of-sight");
    // ... as an ensemble of two, the second member from the next seed, named beside the first.
    assert_eq!(report["config"]["rotation_members"], 2);
    let member = read_json(&out.join("model/member-2/checkpoint.json"));
    assert_eq!(
        member["model"]["seed"],
        checkpoint["model"]["seed"].as_u64().unwrap() + 1
    );
    assert_eq!(member["model"]["rotation_frame"], "line-of-sight");
    let named = read_json(&out.join("model/ensemble.json"));
    assert_eq!(named["members"], json!(["member-2"]));
    // The real frames' scores say they are the two models' and name the rotation estimate,
    // in JSON and in the table's heading.
    assert_eq!(report["real"]["members"], 2);
    let table = std::fs::read_to_string(out.join("eval_real.md")).unwrap();
    assert!(
        table.lines().next().unwrap().ends_with(
            "an ensemble of 2 rotation models, each rotation the centre of its heaviest 15° ball"
        ),
        "{table}"
    );
    // Every real instance of the object is scored, and only those.
    let real = &report["real"];
    let scored: Vec<(u64, u64)> = real["instances"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r: &Value| {
            (
                r["scene_id"].as_u64().unwrap(),
                r["im_id"].as_u64().unwrap(),
            )
        })
        .collect();
    let expected = instances_of(root, OBJ_ID);
    assert_eq!(expected.len(), 2);
    assert_eq!(scored, expected, "{real}");
    assert_eq!(real["obj_id"], OBJ_ID);
    // Both scored with the mesh pipeline's estimate: the heaviest 15° ball's centre.
    assert_eq!(real["ball_deg"], 15.0);
    assert_eq!(report["renders"]["ball_deg"], 15.0);
    for row in real["instances"].as_array().unwrap() {
        let error = row["rotation_error_deg"].as_f64().unwrap();
        let mm = row["translation_error_mm"].as_f64().unwrap();
        assert!(
            (0.0..=180.0).contains(&error) && mm.is_finite() && mm >= 0.0,
            "{row}"
        );
    }
    // The validation renders are scored as a pose: rotation and translation.
    let renders = &report["renders"];
    let images = renders["images"].as_u64().unwrap();
    assert!((1..=4).contains(&images), "{renders}");
    assert!(renders["translation"]["median_error_mm"].as_f64().is_some());
    // ... per render, against the symmetries the real set's models_info.json gives the object
    // (the mustard bottle's half turn), which the renders' models_info.json now carries.
    assert_eq!(
        renders["instances"].as_array().unwrap().len() as u64,
        images
    );
    let symmetries = |path: &Path, id: &str| -> Vec<f64> {
        read_json(path)[id]["symmetries_discrete"]
            .as_array()
            .unwrap()
            .iter()
            .flat_map(|m| m.as_array().unwrap().iter().map(|v| v.as_f64().unwrap()))
            .collect()
    };
    let real_symmetries = symmetries(&root.join("models/models_info.json"), "5");
    let adopted = symmetries(&out.join("data/models/models_info.json"), "1");
    assert_eq!(real_symmetries.len(), 16);
    assert_eq!(adopted.len(), 16);
    for (a, b) in adopted.iter().zip(&real_symmetries) {
        assert!(
            (a - b).abs() < 1e-6,
            "{adopted:?} against {real_symmetries:?}"
        );
    }
    // Pseudo labels only: the training split has labels, and the run read no real pose.
    assert!(out.join("data/train/000000/scene_pseudo_gt.json").exists());
    let markdown = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(markdown.contains("## Real frames"), "{markdown}");
    for figure in ["distribution_real", "rotation_curves", "translation_curves"] {
        let path = out.join("figures").join(format!("{figure}.png"));
        assert!(image::image_dimensions(&path).is_ok(), "{}", path.display());
    }

    // A rerun with other renders is refused, naming the flag.
    let other = setup.words(&setup.camera, &["--distance", "0.5", "1.0"]);
    assert_refused(&other, "distance_m (--distance)");
    let leaning = setup.words(&setup.camera, &["--placement", "leaning"]);
    assert_refused(&leaning, "placement (--placement)");
    let camera_frame = setup.words(&setup.camera, &["--rotation-frame", "camera"]);
    assert_refused(&camera_frame, "rotation_frame (--rotation-frame)");
    let plain = setup.words(&setup.camera, &["--encoder", "small-cnn"]);
    assert_refused(&plain, "encoder (--encoder)");
}

#[test]
fn the_gpu_preset_runs_the_paper_networks_at_the_size_measured_on_a_gpu() {
    let config = Setup::new().recorded_config(&["--preset", "gpu"]);
    // docs/results.md, "One mesh on a GPU": ResNet-18 on 224-pixel crops, a 4 × 256 head,
    // level-2 queries at 1e-4; 3,000 renders, 12 rotation and 4 translation epochs of 200 × 64.
    let expected = json!({"preset": "gpu", "encoder": "resnet18", "input_size": 224,
        "head": "256,256,256,256", "query_level": 2, "learning_rate": 0.0001,
        "frames_per_object": 3000, "val_frames_per_object": 100, "epochs": 12,
        "translation_epochs": 4, "steps_per_epoch": 200, "batch_size": 64,
        "occlusion": [true], "blur": 1.5, "backbones": []});
    for (key, value) in expected.as_object().unwrap() {
        assert_eq!(&config[key], value, "{key}");
    }
}

#[test]
fn the_quick_preset_trains_the_deep_small_cnn_and_the_encoder_flag_overrides_it() {
    let setup = Setup::new();
    // docs/experiments.md, "A deeper small CNN": 64-pixel crops, 128 rotation epochs.
    let preset = setup.recorded_config(&[]);
    assert_eq!(preset["encoder"], "small-cnn-deep");
    assert_eq!(preset["input_size"], 64);
    assert_eq!(preset["epochs"], 128);
    let plain = setup.recorded_config(&["--encoder", "small-cnn"]);
    assert_eq!(plain["encoder"], "small-cnn");
    assert_eq!(plain["epochs"], 128);
    // The labeller's colour rule: off unless asked for, and then recorded.
    assert!(preset.get("appearance_margin").is_none(), "{preset}");
    let coloured = setup.recorded_config(&["--appearance-margin", "0.2"]);
    assert_eq!(coloured["appearance_margin"], 0.2);
    let margin = ipdf(&setup.command(&setup.camera, &["--appearance-margin", "3"]));
    let stderr = String::from_utf8_lossy(&margin.stderr);
    assert!(!margin.status.success());
    assert!(stderr.contains("3: a margin from 0 (off) to 2"), "{stderr}");
    let refused = ipdf(&setup.command(&setup.camera, &["--encoder", "small-cnn-wide"]));
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert!(!refused.status.success());
    assert!(
        stderr.contains("small-cnn-wide: expected one of") && stderr.contains("small-cnn-deep"),
        "{stderr}"
    );
}

#[test]
fn the_pretrained_preset_is_the_configuration_measured_and_says_where_its_weights_come_from() {
    let setup = Setup::new();
    imagenet_weights();
    // docs/results.md, "Every instance with the pretrained encoder": the quick preset with
    // these flags, run from the repository's root.
    let flags = [
        "--encoder",
        "efficientnet-lite0",
        "--pretrained",
        ".pretrained/efficientnet-lite0.safetensors",
        "--freeze-encoder",
        "8",
        "--epochs",
        "48",
        "--learning-rate",
        "0.001",
        "--translation-encoder",
        "small-cnn-deep",
        "--translation-epochs",
        "32",
        "--translation-learning-rate",
        "0.002",
    ];
    let measured = setup.recorded_config_in(&repository(), &flags);
    let preset = setup.recorded_config_in(&repository(), &["--preset", "pretrained"]);
    let (measured, preset) = (measured.as_object().unwrap(), preset.as_object().unwrap());
    assert_eq!(measured["preset"], "quick");
    assert_eq!(preset["preset"], "pretrained");
    let keys: std::collections::BTreeSet<&String> = measured.keys().chain(preset.keys()).collect();
    for key in keys.into_iter().filter(|key| *key != "preset") {
        assert_eq!(measured.get(key), preset.get(key), "{key}");
    }
    // A flag still overrides the preset.
    let longer =
        setup.recorded_config_in(&repository(), &["--preset", "pretrained", "--epochs", "64"]);
    assert_eq!(
        (longer["epochs"].clone(), longer["frozen_blocks"].clone()),
        (json!(64), json!(8))
    );

    // Started elsewhere, the weights are not found: where they come from is said before
    // anything is recorded.
    std::fs::remove_dir_all(&setup.out).unwrap();
    let elsewhere = ipdf_in(
        setup.dir.path(),
        &setup.command(&setup.camera, &["--preset", "pretrained"]),
    );
    let stderr = String::from_utf8_lossy(&elsewhere.stderr);
    assert!(!elsewhere.status.success());
    assert!(
        stderr.contains(".pretrained/efficientnet-lite0.safetensors: no such file")
            && stderr.contains("make setup"),
        "{stderr}"
    );
    assert!(!setup.out.exists());
    // The preset is for a mesh of the user's: without one it is refused.
    let demo = ipdf(&["pipeline", "--preset", "pretrained", "--out", s(&setup.out)]);
    let stderr = String::from_utf8_lossy(&demo.stderr);
    assert!(
        !demo.status.success() && stderr.contains("--mesh"),
        "{stderr}"
    );
    // A freeze without weights to keep is refused too.
    assert_refused(
        &setup.words(
            &setup.camera,
            &["--encoder", "efficientnet-lite0", "--freeze-encoder", "4"],
        ),
        "frozen_blocks: 4 blocks frozen, but no --pretrained weights",
    );
    assert!(!setup.out.exists());
}

#[test]
fn a_real_split_without_masks_is_warned_of_before_the_renders() {
    let setup = Setup::new();
    // A file in the way of the renders stops each run right after its checks.
    std::fs::create_dir_all(&setup.out).unwrap();
    std::fs::write(setup.out.join("data"), "in the way").unwrap();
    let stderr = |real: &Path| {
        let extra = ["--real", s(real), "--obj-id", "5"];
        std::fs::remove_file(setup.out.join("pipeline_config.json")).ok();
        let output = ipdf(&setup.command(&setup.camera, &extra));
        assert!(!output.status.success());
        String::from_utf8(output.stderr).unwrap()
    };
    // LM-O's real frame has boxes and no masks; YCB-Video's has masks.
    let lmo = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/lmo_real");
    let warned = stderr(&lmo);
    assert!(
        warned.contains("warning: split \"test\"") && warned.contains("no visible masks"),
        "{warned}"
    );
    let quiet = stderr(&setup.root);
    assert!(!quiet.contains("no visible masks"), "{quiet}");
}

#[test]
fn a_mesh_run_refuses_what_it_cannot_use() {
    let setup = Setup::new();
    let camera = &setup.camera;
    let far_first = setup.words(camera, &["--distance", "1.2", "0.4"]);
    assert_refused(&far_first, "--distance must be two distances");
    let fog = setup.words(camera, &["--randomize", "lights,fog"]);
    assert_refused(&fog, "unknown part \"fog\"");
    let split = setup.words(camera, &["--real-split", "tset"]);
    assert_refused(
        &split,
        "split \"tset\" does not exist; the dataset's splits: test",
    );
    let bad = setup.dir.path().join("bad.json");
    std::fs::write(&bad, r#"{"fx": 500}"#).unwrap();
    assert_refused(&setup.words(&bad, &[]), "bad.json");
    assert!(!setup.out.exists());
}

/// EfficientNet-Lite0's ImageNet weights, as `make setup` converts them.
fn imagenet_weights() -> PathBuf {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../.pretrained/efficientnet-lite0.safetensors");
    assert!(
        path.exists(),
        "{} is missing: run scripts/setup-pretrained.sh (make test does)",
        path.display()
    );
    path
}

/// The tensors of the last `model-*.safetensors` in `run`, by name.
fn saved_tensors(run: &Path) -> std::collections::HashMap<String, tch::Tensor> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(run)
        .unwrap()
        .map(|entry| entry.unwrap().path())
        .filter(|path| {
            let name = path.file_name().unwrap().to_string_lossy();
            name.starts_with("model-") && name.ends_with(".safetensors")
        })
        .collect();
    files.sort();
    let last = files
        .last()
        .unwrap_or_else(|| panic!("no model in {}", run.display()));
    tch::Tensor::read_safetensors(last)
        .unwrap()
        .into_iter()
        .collect()
}

#[test]
fn pretrained_weights_start_both_models_and_their_frozen_blocks_stay_as_given() {
    let setup = Setup::new();
    let weights = imagenet_weights();
    let words = setup.pretrained_run(&weights, "16", &["--learning-rate", "0.001"]);
    ipdf_json(&words);
    let config = read_json(&setup.out.join("pipeline_config.json"));
    assert_eq!(config["pretrained"], s(&weights));
    assert_eq!(config["frozen_blocks"], 16);
    assert_eq!(config["learning_rate"], 0.001);
    assert_eq!(config["translation_learning_rate"], 0.001);
    let report = std::fs::read_to_string(setup.out.join("report.md")).unwrap();
    assert!(report.contains("(16 blocks frozen)"), "{report}");
    // The oracle is the weights file itself: what is frozen is the file's to the bit, in the
    // rotation and in the translation model, and what trains has moved away from it.
    let imagenet: std::collections::HashMap<String, tch::Tensor> =
        tch::Tensor::read_safetensors(&weights)
            .unwrap()
            .into_iter()
            .collect();
    for run in [setup.out.join("model"), setup.out.join("model/translation")] {
        let checkpoint = read_json(&run.join("checkpoint.json"));
        let model = &checkpoint["model"];
        assert_eq!(model["frozen_blocks"], 16, "{}", run.display());
        assert_eq!(model["encoder"], "efficientnet-lite0");
        let saved = saved_tensors(&run);
        for name in [
            "_conv_stem.weight",
            "_blocks.0._depthwise_conv.weight",
            "_blocks.15._project_conv.weight",
        ] {
            let trained = &saved[&format!("encoder.{name}")];
            assert!(
                trained.equal(&imagenet[name]),
                "{}: {name} moved",
                run.display()
            );
        }
        // The 1×1 convolution after the blocks is not frozen: it starts from the file and
        // trains.
        let head = &saved["encoder._conv_head.weight"];
        assert!(
            !head.equal(&imagenet["_conv_head.weight"]),
            "{}",
            run.display()
        );
    }
}

#[test]
fn pretrained_weights_that_do_not_fit_are_refused_before_the_renders() {
    let setup = Setup::new();
    let weights = imagenet_weights();
    // The preset's small CNN has no ImageNet weights: the file is named, nothing is rendered.
    let small = setup.words(&setup.camera, &["--pretrained", s(&weights)]);
    assert_refused(&small, "efficientnet-lite0.safetensors");
    assert!(!setup.out.join("data").exists());
    let missing = setup.dir.path().join("missing.safetensors");
    let absent = setup.words(
        &setup.camera,
        &[
            "--encoder",
            "efficientnet-lite0",
            "--pretrained",
            s(&missing),
        ],
    );
    assert_refused(&absent, "missing.safetensors: no such file");
    // The cause is said once, though the error shows its source.
    let stderr = String::from_utf8(ipdf(&absent).stderr).unwrap();
    assert_eq!(stderr.matches("no such file").count(), 1, "{stderr}");
    let too_many = setup.words(
        &setup.camera,
        &[
            "--encoder",
            "efficientnet-lite0",
            "--pretrained",
            s(&weights),
            "--freeze-encoder",
            "17",
        ],
    );
    assert_refused(&too_many, "frozen_blocks");
    assert_refused(
        &setup.words(&setup.camera, &["--learning-rate", "0"]),
        "a learning rate over 0",
    );
    assert!(!setup.out.join("data").exists());
}

#[test]
fn a_translation_encoder_of_its_own_trains_from_its_own_weights() {
    let setup = Setup::new();
    // A copy of the weights, taken away once the models are trained.
    let weights = setup.dir.path().join("lite0.safetensors");
    std::fs::copy(imagenet_weights(), &weights).unwrap();
    let extra = ["--translation-encoder", "small-cnn-deep"];
    let words = setup.pretrained_run(&weights, "4", &extra);
    ipdf_json(&words);
    let config = read_json(&setup.out.join("pipeline_config.json"));
    assert_eq!(config["translation_encoder"], "small-cnn-deep");
    // The weights and the freeze are the rotation model's encoder's.
    let rotation = read_json(&setup.out.join("model/checkpoint.json"));
    assert_eq!(rotation["model"]["encoder"], "efficientnet-lite0");
    assert_eq!(rotation["model"]["frozen_blocks"], 4);
    let translation = read_json(&setup.out.join("model/translation/checkpoint.json"));
    assert_eq!(translation["model"]["encoder"], "small-cnn-deep");
    assert!(
        translation["model"].get("frozen_blocks").is_none(),
        "{translation}"
    );
    let report = std::fs::read_to_string(setup.out.join("report.md")).unwrap();
    assert!(report.contains("(translation: small-cnn-deep)"), "{report}");
    // A rerun with the translation model's encoder changed is refused, naming the flag.
    let other = [&words[..words.len() - 1], &["small-cnn"]].concat();
    assert_refused(&other, "translation_encoder (--translation-encoder)");
    // Trained models read the weights no more: without the file the report is written again.
    std::fs::remove_file(&weights).unwrap();
    std::fs::remove_file(setup.out.join("report.md")).unwrap();
    ipdf_json(&words);
    assert!(setup.out.join("report.md").exists());
}
