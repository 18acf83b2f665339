//! Ensembles of rotation models through the real binary: `train --members` writes the members
//! and names them; `predict`, `eval` and `viz` read the folder as one model whose density is
//! the normalised geometric mean of the members' (each member's own prediction is the oracle);
//! bad member counts are refused.
use crate::common;

use std::path::Path;

use common::{
    BRIEF_TRAINING, SMALL_NETWORK, assert_fails, copy_dir, ipdf_json, predict_args, read_json,
    read_npy, s, synth, train_single, viz_args,
};

#[test]
fn an_ensemble_predicts_the_normalised_geometric_mean_of_its_members() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    for (split, frames, seed) in [("train", 8, "0"), ("val", 2, "1")] {
        synth(&data, "box", frames, &["--split", split, "--seed", seed]);
    }
    let run = dir.path().join("run");
    let mut words = train_single(&data, "box");
    words.extend(["--out", s(&run), "--members", "2"]);
    words.extend(SMALL_NETWORK);
    words.extend(BRIEF_TRAINING);
    let trained = ipdf_json(&words);
    // The first member in --out, the second in member-2 from the next seed, named in
    // ensemble.json.
    let member = run.join("member-2");
    assert_eq!(trained["members"][0]["run"], s(&member));
    assert_eq!(
        read_json(&run.join("ensemble.json"))["members"],
        serde_json::json!(["member-2"])
    );
    assert_eq!(read_json(&run.join("checkpoint.json"))["model"]["seed"], 0);
    assert_eq!(
        read_json(&member.join("checkpoint.json"))["model"]["seed"],
        1
    );
    // A second call finds both trained.
    let again = ipdf_json(&words);
    assert_eq!(again["epochs_run"], 0);
    assert_eq!(again["members"][0]["epochs_run"], 0);

    // Each member alone: the first in a copy without ensemble.json, the second in its folder.
    let first = dir.path().join("first");
    copy_dir(&run, &first);
    std::fs::remove_file(first.join("ensemble.json")).unwrap();
    let scene = data.join("val/000000");
    let (rgb, mask) = (
        scene.join("rgb/000000.png"),
        scene.join("mask_visib/000000_000000.png"),
    );
    let predict = |model: &Path, name: &str| {
        let out = dir.path().join(name);
        let predicted = ipdf_json(&predict_args(model, &rgb, &mask, &out, &["--level", "2"]));
        (predicted, read_npy(&out).1)
    };
    let (_, a) = predict(&first, "a.npy");
    let (_, b) = predict(&member, "b.npy");
    let (together, masses) = predict(&run, "ensemble.npy");
    assert_eq!(together["cells"], 4_608);
    let product: Vec<f64> = a
        .iter()
        .zip(&b)
        .map(|(&p, &q)| (f64::from(p) * f64::from(q)).sqrt())
        .collect();
    let total: f64 = product.iter().sum();
    for (i, (&m, g)) in masses.iter().zip(&product).enumerate() {
        let expected = g / total;
        assert!(
            (f64::from(m) - expected).abs() <= 1e-4 * expected + 1e-9,
            "cell {i}: {m} against {expected}"
        );
    }
    // The members disagree, so the ensemble is neither.
    assert!(a.iter().zip(&masses).any(|(p, m)| (p - m).abs() > 1e-6));

    // eval and viz read the folder as one model.
    let scores = ipdf_json(&["eval", "--checkpoint", s(&run), "--level", "2"]);
    let alone = ipdf_json(&["eval", "--checkpoint", s(&first), "--level", "2"]);
    assert_eq!(scores["images"], alone["images"]);
    assert_ne!(scores["llh"], alone["llh"]);
    // The scores say how many models made them; one model's leave the key out.
    assert_eq!(scores["members"], 2);
    assert!(alone.get("members").is_none(), "{alone}");
    // viz draws the ensemble's distribution: the figure has the size it reports and is not
    // the first member's alone.
    let figure = dir.path().join("ensemble.png");
    let member_figure = dir.path().join("member.png");
    let drawn = ["--scene", "0", "--image", "0"];
    let reported = ipdf_json(&viz_args(&run, &figure, &drawn));
    ipdf_json(&viz_args(&first, &member_figure, &drawn));
    let (ensemble_image, member_image) = (
        image::open(&figure).unwrap().to_rgb8(),
        image::open(&member_figure).unwrap().to_rgb8(),
    );
    assert_eq!(
        (reported["width"].as_u64(), reported["height"].as_u64()),
        (
            Some(u64::from(ensemble_image.width())),
            Some(u64::from(ensemble_image.height()))
        )
    );
    assert_eq!(ensemble_image.dimensions(), member_image.dimensions());
    assert!(
        ensemble_image != member_image,
        "the ensemble is drawn as its first member"
    );

    // A member named but missing is refused, naming the file; as is a count out of range, or
    // an ensemble of translation models.
    std::fs::write(
        run.join("ensemble.json"),
        r#"{"members": ["member-2", "member-3"]}"#,
    )
    .unwrap();
    assert_fails(
        &["eval", "--checkpoint", s(&run), "--level", "2"],
        "member-3",
    );
    let mut zero = train_single(&data, "box");
    zero.extend(["--out", s(&run), "--members", "0"]);
    assert_fails(&zero, "--members");
    let mut translation = train_single(&data, "box");
    let elsewhere = dir.path().join("translation");
    translation.extend([
        "--out",
        s(&elsewhere),
        "--members",
        "2",
        "--target",
        "translation",
    ]);
    assert_fails(&translation, "only rotation models form ensembles");
}
