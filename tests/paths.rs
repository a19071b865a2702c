//! Any path: a path corrector trained on random tours, judged on held-out UMBMark squares
//! (Borenstein's E_max,syst) and held-out tours (end error per metre driven) against raw
//! odometry, UMBMark's own E_d/E_b calibration, the kinematic fit and the oracle with the
//! simulator's true kinematics.

mod common;
use common::{fails, ok};

use serde_json::Value;

fn method<'a>(ev: &'a Value, prefix: &str) -> &'a Value {
    ev["methods"]
        .as_array()
        .unwrap()
        .iter()
        .find(|m| m["name"].as_str().unwrap().starts_with(prefix))
        .unwrap_or_else(|| panic!("no method {prefix} in {ev}"))
}

fn e_max(ev: &Value, prefix: &str) -> f64 {
    method(ev, prefix)["umbmark"]["e_max_syst_m"]
        .as_f64()
        .unwrap()
}

fn per_m(ev: &Value, prefix: &str) -> f64 {
    method(ev, prefix)["end_error_per_m"].as_f64().unwrap()
}

#[test]
fn a_path_corrector_trained_on_tours_closes_held_out_squares_as_well_as_the_true_kinematics() {
    let dir = tempfile::tempdir().unwrap();
    let d = |p: &str| dir.path().join(p).display().to_string();
    let synth = |paths: &str, runs: &str, seed: &str, out: &str| {
        ok(&[
            "synth",
            "experiment",
            "--paths",
            paths,
            "--runs",
            runs,
            "--frames",
            "none",
            "--seed",
            seed,
            "--out",
            &d(out),
        ]);
    };
    synth("tours", "40", "11", "train");
    synth("umbmark", "10", "12", "squares-cal");
    synth("umbmark", "10", "13", "squares");
    synth("tours", "10", "14", "tours");
    let out = ok(&[
        "dataset",
        "--manifest",
        &d("train/manifest.json"),
        "--layout",
        "windows",
        "--out",
        &d("windows.json"),
        "--truth",
        &d("train/truth/oracle.json"),
    ]);
    println!("{out}");
    let out = ok(&["train", &d("windows.json"), "--out", &d("path-model.json")]);
    println!("{out}");
    // A window dataset is no straight-run sweep.
    fails(&["train", &d("windows.json"), "--sweep", "1..2"]);

    ok(&[
        "evaluate",
        &d("squares/manifest.json"),
        "--model",
        &d("path-model.json"),
        "--umbmark-m",
        "4",
        "--umbmark-calibration",
        &d("squares-cal/manifest.json"),
        "--truth",
        &d("squares/truth/oracle.json"),
        "--out",
        &d("squares.json"),
    ]);
    let sq: Value =
        serde_json::from_str(&std::fs::read_to_string(d("squares.json")).unwrap()).unwrap();
    let (raw, umb, kin, net, orc) = (
        e_max(&sq, "raw"),
        e_max(&sq, "UMBMark"),
        e_max(&sq, "kinematic"),
        e_max(&sq, "perceptron"),
        e_max(&sq, "oracle"),
    );
    println!(
        "UMBMark E_max,syst on 5+5 held-out 4 m squares: raw {:.0} mm, UMBMark calibration {:.0} mm, kinematic fit {:.0} mm, perceptron {:.0} mm, oracle {:.0} mm (perceptron/oracle {:.2})",
        1e3 * raw, 1e3 * umb, 1e3 * kin, 1e3 * net, 1e3 * orc, net / orc
    );
    assert!(
        net <= umb && net <= kin,
        "perceptron {net} vs UMBMark {umb}, kinematic fit {kin}"
    );
    assert!(net <= 1.3 * orc, "perceptron {net} vs oracle {orc}");
    assert!(net < 0.1 * raw, "perceptron {net} vs raw {raw}");

    ok(&[
        "evaluate",
        &d("tours/manifest.json"),
        "--model",
        &d("path-model.json"),
        "--truth",
        &d("tours/truth/oracle.json"),
        "--out",
        &d("tours.json"),
    ]);
    let tours: Value =
        serde_json::from_str(&std::fs::read_to_string(d("tours.json")).unwrap()).unwrap();
    let (raw, kin, net, orc) = (
        per_m(&tours, "raw"),
        per_m(&tours, "kinematic"),
        per_m(&tours, "perceptron"),
        per_m(&tours, "oracle"),
    );
    println!(
        "held-out tours, end error per metre driven: raw {:.2} %, kinematic fit {:.2} %, perceptron {:.2} %, oracle {:.2} % (perceptron/oracle {:.2})",
        100.0 * raw, 100.0 * kin, 100.0 * net, 100.0 * orc, net / orc
    );
    assert!(net <= 1.3 * orc, "perceptron {net} vs oracle {orc}");
    assert!(
        net < kin && net < 0.25 * raw,
        "{net} vs kinematic {kin}, raw {raw}"
    );

    // `odocal correct` with the path model writes the whole corrected trajectory; its end is
    // the perceptron's end in the evaluation.
    let out = ok(&[
        "correct",
        "--model",
        &d("path-model.json"),
        &d("tours/runs/run001.odometry.csv"),
        "--out",
        &d("corrected.csv"),
    ]);
    assert!(out.contains("corrected end"), "{out}");
    let csv = std::fs::read_to_string(d("corrected.csv")).unwrap();
    let last: Vec<f64> = csv
        .lines()
        .last()
        .unwrap()
        .split(',')
        .map(|v| v.parse().unwrap())
        .collect();
    let run = &tours["runs"][0];
    let i = tours["methods"]
        .as_array()
        .unwrap()
        .iter()
        .position(|m| m["name"].as_str().unwrap().starts_with("perceptron"))
        .unwrap();
    let truth = [
        run["true_end_m"][0].as_f64().unwrap(),
        run["true_end_m"][1].as_f64().unwrap(),
    ];
    let err = [
        run["errors_m"][i][0].as_f64().unwrap(),
        run["errors_m"][i][1].as_f64().unwrap(),
    ];
    assert!((last[4] - (truth[0] - err[0])).abs() < 1e-5, "{last:?}");
    assert!((last[5] - (truth[1] - err[1])).abs() < 1e-5, "{last:?}");

    // Wrong files in the wrong place.
    fails(&[
        "evaluate",
        &d("tours/manifest.json"),
        "--model",
        &d("windows.json"),
    ]);
    let e = fails(&[
        "evaluate",
        &d("tours/manifest.json"),
        "--model",
        &d("path-model.json"),
        "--umbmark-m",
        "4",
    ]);
    assert!(e.contains("no UMBMark square"), "{e}");
    // A held-out log with its left and right columns swapped is judged against the same
    // checks as a dataset's, not scored as a bad method.
    let log = std::path::PathBuf::from(d("tours/runs/run001.odometry.csv"));
    let text = std::fs::read_to_string(&log).unwrap();
    let swapped: Vec<String> = text
        .lines()
        .enumerate()
        .map(|(i, l)| {
            let c: Vec<&str> = l.split(',').collect();
            if i == 0 {
                return l.to_string();
            }
            format!("{},{},{}", c[0], c[2], c[1])
        })
        .collect();
    std::fs::write(&log, swapped.join("\n")).unwrap();
    let e = fails(&[
        "evaluate",
        &d("tours/manifest.json"),
        "--model",
        &d("path-model.json"),
    ]);
    assert!(
        e.contains("are the log's left and right columns swapped"),
        "{e}"
    );
}
