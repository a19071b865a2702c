//! Bad and unusual inputs, as a new user passes them: each class gives exit code 2, one line
//! that names the culprit, and no output file; none gives a plausible wrong answer.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use common::{experiment_dataset, fails, fails_with, odocal, ok, p, succeeded};

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/parsers")
        .join(name)
}

/// The files of a directory (to check that nothing was written).
fn listing(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .map(|r| {
            r.filter_map(|e| e.ok())
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}

/// Runs odocal expecting the one-line error containing every `needles`, and checks that
/// `dir` holds the same files afterwards.
fn refused(dir: &Path, args: &[&str], needles: &[&str]) {
    let before = listing(dir);
    let e = fails(args);
    for n in needles {
        assert!(e.contains(n), "expected {n:?} in: {e}");
    }
    assert_eq!(listing(dir), before, "files appeared for {args:?}");
}

#[test]
fn correct_refuses_logs_outside_the_training_domain() {
    let d = tempfile::tempdir().expect("tempdir");
    let dir = d.path();
    let ds = dir.join("dataset.json");
    experiment_dataset(&dir.join("exp"), &ds, 30, 4);
    let model = dir.join("model.json");
    ok(&[
        "train",
        p(&ds),
        "--out",
        p(&model),
        "--hidden",
        "4",
        "--no-cv",
    ]);
    let log_path = dir.join("exp/runs/run001.odometry.csv");
    ok(&["correct", "--model", p(&model), p(&log_path)]);
    let text = std::fs::read_to_string(&log_path).expect("log");
    let scaled = |k: i64| -> String {
        let mut lines = text.lines();
        let mut out = format!("{}\n", lines.next().unwrap_or(""));
        for l in lines {
            let f: Vec<&str> = l.split(',').collect();
            let n = |s: &str| s.parse::<i64>().expect("ticks") * k;
            out += &format!("{},{},{}\n", f[0], n(f[1]), n(f[2]));
        }
        out
    };
    let out = dir.join("corrected.csv");
    let long = dir.join("long.csv");
    std::fs::write(&long, scaled(10)).expect("write");
    refused(
        dir,
        &["correct", "--model", p(&model), p(&long), "--out", p(&out)],
        &[
            "long.csv",
            "outside what the model was trained on",
            "m from its start",
        ],
    );
    // Times in milliseconds: every row 1000 periods apart, and said so.
    let ms: String = text
        .lines()
        .enumerate()
        .map(|(i, l)| match l.split_once(',') {
            Some((t, rest)) if i > 0 => {
                format!("{},{rest}\n", t.parse::<f64>().expect("time") * 1000.0)
            }
            _ => format!("{l}\n"),
        })
        .collect();
    let ms_log = dir.join("ms.csv");
    std::fs::write(&ms_log, ms).expect("write");
    refused(
        dir,
        &[
            "correct",
            "--model",
            p(&model),
            p(&ms_log),
            "--out",
            p(&out),
        ],
        &["ms.csv: rows are 200.000 s apart", "in milliseconds?"],
    );
    // A robot clock 100 s on: the refusal names input 16 as the run's start on that clock.
    let late: String = text
        .lines()
        .enumerate()
        .map(|(i, l)| match l.split_once(',') {
            Some((t, rest)) if i > 0 => {
                format!("{},{rest}\n", t.parse::<f64>().expect("time") + 100.0)
            }
            _ => format!("{l}\n"),
        })
        .collect();
    let late_log = dir.join("late.csv");
    std::fs::write(&late_log, late).expect("write");
    refused(
        dir,
        &[
            "correct",
            "--model",
            p(&model),
            p(&late_log),
            "--out",
            p(&out),
        ],
        &["input 16 = ", "t_b, the run's start on the robot's clock"],
    );
    let back = dir.join("back.csv");
    std::fs::write(&back, scaled(-1)).expect("write");
    refused(
        dir,
        &["correct", "--model", p(&model), p(&back), "--out", p(&out)],
        &["behind its start"],
    );
    // On request it is corrected, and flagged on stderr.
    let o = odocal(&[
        "correct",
        "--model",
        p(&model),
        p(&back),
        "--allow-extrapolation",
    ]);
    assert!(o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("EXTRAPOLATED"));

    // A model whose robot has no physical sense is refused, naming the field.
    let bad = dir.join("bad_model.json");
    let m = std::fs::read_to_string(&model).expect("model");
    let v: serde_json::Value = serde_json::from_str(&m).expect("json");
    let wd = v["robot"]["wheel_diameter_m"].as_f64().expect("diameter");
    let mut v2 = v.clone();
    v2["robot"]["wheel_diameter_m"] = serde_json::json!(-wd);
    std::fs::write(&bad, v2.to_string()).expect("write");
    refused(
        dir,
        &[
            "correct",
            "--model",
            p(&bad),
            p(&log_path),
            "--out",
            p(&out),
        ],
        &["bad_model.json", "wheel_diameter_m"],
    );
}

#[test]
fn camera_files_without_physical_sense_name_the_field() {
    let d = tempfile::tempdir().expect("tempdir");
    let dir = d.path();
    let cam: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(data("camera.json")).expect("camera"))
            .expect("json");
    let out = dir.join("traj.csv");
    let video = dir.join("none.avi");
    for (field, value, needle) in [
        ("fx", serde_json::json!(0.0), "fx = 0"),
        ("fy", serde_json::json!(-5.0), "fy = -5"),
    ] {
        let mut c = cam.clone();
        c["camera"]["intrinsics"][field] = value;
        let path = dir.join(format!("cam_{field}.json"));
        std::fs::write(&path, c.to_string()).expect("write");
        refused(
            dir,
            &["track", p(&video), "--camera", p(&path), "--out", p(&out)],
            &[&format!("cam_{field}.json"), needle],
        );
    }
    let mut c = cam.clone();
    c["floor"]["floor_to_camera"]["rotation"] = serde_json::json!([0.0, 0.0, 0.0, 0.0]);
    let zero = dir.join("cam_rot.json");
    std::fs::write(&zero, c.to_string()).expect("write");
    let e = fails(&["track", p(&video), "--camera", p(&zero), "--out", p(&out)]);
    assert!(e.contains("cam_rot.json"), "{e}");
    assert!(!out.exists());
    // The board block fed `arena` a raw OpenCV error (cols 0) or a square of -0.07 m with exit
    // 0; a pose putting the camera below the floor was blamed on --tag-size.
    let mut edits: Vec<(&str, serde_json::Value, &str)> = Vec::new();
    let mut c = cam.clone();
    c["board"]["cols"] = serde_json::json!(0);
    edits.push(("cols", c, "board is 0x6"));
    let mut c = cam.clone();
    c["board"]["square_m"] = serde_json::json!(-0.07);
    edits.push(("square", c, "board.square_m = -0.07"));
    let mut c = cam.clone();
    c["floor"]["floor_to_camera"]["translation"][2] = serde_json::json!(-2.189);
    edits.push(("below", c, "floor.floor_to_camera puts the camera"));
    // A focal length in millimetres was blamed on --tag-size by `track` and on the file order
    // by `arena`.
    let mut c = cam.clone();
    c["camera"]["intrinsics"]["fx"] = serde_json::json!(3.6);
    edits.push(("mm", c, "focal lengths are in pixels"));
    // A focal length of 1e300 px, or fx three times fy, loaded and tracked with exit 0.
    let mut c = cam.clone();
    c["camera"]["intrinsics"]["fx"] = serde_json::json!(1e300);
    edits.push((
        "huge",
        c,
        "fx = 1.000000e300 px gives a field of view under 0.6 degrees",
    ));
    let mut c = cam.clone();
    let fy = c["camera"]["intrinsics"]["fy"].as_f64().unwrap_or(1000.0);
    c["camera"]["intrinsics"]["fx"] = serde_json::json!(3.0 * fy);
    edits.push(("aspect", c, "no camera's pixels are that far from square"));
    // A floor uncertainty map cut short, or of negative σ, changed every fix's σ with exit 0.
    let map = |sigma: Vec<serde_json::Value>| {
        serde_json::json!({"cell_px": 40, "cols": 32, "rows": 18, "sigma_mm": sigma,
            "floor_boards_px": []})
    };
    let mut c = cam.clone();
    c["floor_uncertainty"] = map(vec![serde_json::json!(0.2); 100]);
    edits.push(("cut", c, "floor_uncertainty has 100 sigma_mm"));
    let mut c = cam.clone();
    c["floor_uncertainty"] = map(vec![serde_json::json!(-1.0); 576]);
    edits.push(("negative", c, "not a standard deviation"));
    // The per-cell covariance behind σ, which `track` takes each fix's σ from: cut short, or
    // with a correlation beyond ±1.
    let with_covariance = |cells: usize, xy: f64| {
        let mut m = map(vec![serde_json::json!(0.2); 576]);
        m["covariance_mm2"] = serde_json::json!(vec![[0.04, xy, 0.01]; cells]);
        m
    };
    let mut c = cam.clone();
    c["floor_uncertainty"] = with_covariance(100, 0.0);
    edits.push((
        "cov_cut",
        c,
        "floor_uncertainty has 100 covariance_mm2 values",
    ));
    let mut c = cam.clone();
    c["floor_uncertainty"] = with_covariance(576, 0.05);
    edits.push((
        "cov_corr",
        c,
        "floor_uncertainty.covariance_mm2 entry 0 is not a covariance",
    ));
    // A floor covariance with a σ of metres, or not symmetric, widened every arena fix's σ
    // with exit 0.
    let covariance = |turn_var: f64, skew: f64| {
        let n = 15; // the floor pose's 6 and pinhole5's 9 parameters
        let rows: Vec<Vec<f64>> = (0..n)
            .map(|i| {
                (0..n)
                    .map(|j| match (i, j) {
                        _ if i == j && i < 3 => turn_var,
                        _ if i == j => 1e-6,
                        (0, 1) => skew,
                        _ => 0.0,
                    })
                    .collect()
            })
            .collect();
        let mut m = map(vec![serde_json::json!(0.2); 576]);
        m["floor_covariance"] = serde_json::json!(rows);
        m
    };
    let mut c = cam.clone();
    c["floor_uncertainty"] = covariance(0.25, 0.0);
    edits.push(("floor_sigma", c, "σ of 500.0 mrad (turn)"));
    let mut c = cam.clone();
    c["floor_uncertainty"] = covariance(1e-6, 1e-7);
    edits.push(("asymmetric", c, "floor_covariance is not symmetric"));
    for (name, c, needle) in edits {
        let path = dir.join(format!("cam_{name}.json"));
        std::fs::write(&path, c.to_string()).expect("write");
        refused(
            dir,
            &["track", p(&video), "--camera", p(&path), "--out", p(&out)],
            &[&format!("cam_{name}.json"), needle],
        );
    }
    // A rotation typed in with five decimals (norm 1 ± 1e-5) is a rotation: the run goes on
    // to the (missing) video.
    let mut c = cam.clone();
    for v in c["floor"]["floor_to_camera"]["rotation"]
        .as_array_mut()
        .expect("rotation")
    {
        *v = serde_json::json!((v.as_f64().expect("number") * 1e5).round() / 1e5);
    }
    let rounded = dir.join("cam_rounded.json");
    std::fs::write(&rounded, c.to_string()).expect("write");
    let e = fails(&[
        "track",
        p(&video),
        "--camera",
        p(&rounded),
        "--out",
        p(&out),
    ]);
    assert!(e.contains("none.avi") && !e.contains("rotation"), "{e}");
}

#[test]
fn laser_options_and_scan_times_are_checked() {
    let d = tempfile::tempdir().expect("tempdir");
    let dir = d.path();
    let (map, scans) = (data("map.json"), data("scans.csv"));
    let out = dir.join("poses.csv");
    let base = [
        "lrf",
        "localize",
        "--map",
        p(&map),
        p(&scans),
        "--out",
        p(&out),
    ];
    for (opt, v, needle) in [
        ("--rate-hz", "0", "--rate-hz"),
        ("--max-range-m", "-5", "--max-range-m"),
        ("--sigma-range-m", "-1", "--sigma-range-m"),
        ("--intensity-min", "NaN", "--intensity-min"),
        // 240° typed in radians was taken (the scans' own angles span 240°).
        (
            "--fov-deg",
            "4.18",
            "--fov-deg 4.18: the scans' beams span 239.",
        ),
        ("--fov-deg", "4.18", "(if 4.18 is in radians, it is 239.5°)"),
    ] {
        let mut args = base.to_vec();
        let arg = format!("{opt}={v}");
        args.push(&arg);
        refused(dir, &args, &[needle]);
    }
    // A range too short for the room was put as a unit mistake ("if these are centimetres,
    // 2.882 is 0.029 m"). (The map's landmarks are named as isolated at that range first.)
    let mut args = base.to_vec();
    args.push("--max-range-m=1");
    let res = odocal(&args);
    let e = String::from_utf8_lossy(&res.stderr);
    assert_eq!(res.status.code(), Some(2), "{e}");
    assert!(
        e.lines().last().unwrap_or_default().contains(
            "median range is 2.808 m, beyond twice --max-range-m 1 m, so most returns would be dropped"
        ) && !e.contains("centimetres"),
        "{e}"
    );
    refused(
        dir,
        &["lrf", "check-map", p(&map), "--max-range-m=-1"],
        &["--max-range-m"],
    );
    // A negative value after a space is the option's value, checked by odocal, not an
    // unknown argument ("tip: to pass '-1' as a value, use '-- -1'").
    let mut args = base.to_vec();
    args.extend(["--sigma-range-m", "-1"]);
    refused(dir, &args, &["--sigma-range-m -1"]);
    let text = std::fs::read_to_string(&scans).expect("scans");
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    // A second scan (id 1) whose time is NaN, the same as the first, earlier, or absurd.
    let second: Vec<String> = lines[1..]
        .iter()
        .map(|l| l.replacen("0,", "1,", 1))
        .collect();
    for (t, needle) in [
        ("NaN", "scans2.csv"),
        ("0.000", "time order"),
        ("-1", "not a scan time"),
        ("1e12", "not a scan time"),
    ] {
        let mut all = lines.clone();
        all.extend(second.iter().map(|l| {
            let mut f: Vec<&str> = l.split(',').collect();
            f[1] = t;
            f.join(",")
        }));
        let bad = dir.join("scans2.csv");
        std::fs::write(&bad, all.join("\n") + "\n").expect("write");
        let mut args = base.to_vec();
        args[4] = p(&bad);
        refused(dir, &args, &[needle]);
        std::fs::remove_file(&bad).expect("remove");
    }
    lines.truncate(1);
}

#[test]
fn absurd_maps_are_refused_without_a_hang_or_a_huge_allocation() {
    let d = tempfile::tempdir().expect("tempdir");
    let dir = d.path();
    let map: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(data("map.json")).expect("map"))
            .expect("json");
    for (name, f) in [("far", 1e300), ("mm", 1000.0), ("km", 1e7)] {
        let mut m = map.clone();
        if let Some(ls) = m["landmarks"].as_array_mut() {
            for (k, l) in ls.iter_mut().enumerate() {
                let x = l["x_m"].as_f64().unwrap_or(0.0);
                l["x_m"] = serde_json::json!(if name == "mm" || k == 0 { x * f + f } else { x });
            }
        }
        let path = dir.join(format!("{name}.json"));
        std::fs::write(&path, m.to_string()).expect("write");
        refused(
            dir,
            &["lrf", "check-map", p(&path)],
            &[&format!("{name}.json"), "are the coordinates in metres?"],
        );
    }
    // Reflector orientations in degrees: named, with the value in radians.
    for (field, deg, needle) in [
        ("facing_rad", 90.0, "facing_rad 90 is beyond a full turn"),
        ("half_fov_rad", 75.0, "75° is 1.3090 rad"),
    ] {
        let mut m = map.clone();
        m["landmarks"][0][field] = serde_json::json!(deg);
        let path = dir.join(format!("{field}.json"));
        std::fs::write(&path, m.to_string()).expect("write");
        refused(
            dir,
            &["lrf", "check-map", p(&path)],
            &[&format!("{field}.json"), needle, "angles are in radians"],
        );
    }
}

#[test]
fn outputs_are_plain_files_and_appear_together_or_not_at_all() {
    let d = tempfile::tempdir().expect("tempdir");
    let dir = d.path();
    let (map, scans) = (data("map.json"), data("scans.csv"));
    // A directory, a device: refused before any work, nothing replaced.
    for out in [dir.to_path_buf(), PathBuf::from("/dev/null")] {
        refused(
            dir,
            &[
                "lrf",
                "localize",
                "--map",
                p(&map),
                p(&scans),
                "--out",
                p(&out),
            ],
            &["--out", "give a file path"],
        );
    }
    // An output that is one of the inputs, or another output (however spelt): refused,
    // the input untouched.
    let scans_copy = dir.join("scans.csv");
    std::fs::copy(&scans, &scans_copy).expect("copy");
    let before = std::fs::read(&scans_copy).expect("read");
    let dotted = format!("--out={}/./scans.csv", p(dir));
    refused(
        dir,
        &["lrf", "localize", "--map", p(&map), p(&scans_copy), &dotted],
        &["is the same file as the argument", "scans.csv"],
    );
    assert_eq!(std::fs::read(&scans_copy).expect("read"), before);
    // Through a folder that does not exist yet: the folder would be made and the input
    // replaced.
    let through_new = format!("{}/not-yet/../scans.csv", p(dir));
    refused(
        dir,
        &[
            "lrf",
            "localize",
            "--map",
            p(&map),
            p(&scans_copy),
            "--out",
            &through_new,
        ],
        &["is the same file as the argument", "scans.csv"],
    );
    assert_eq!(std::fs::read(&scans_copy).expect("read"), before);
    assert!(!dir.join("not-yet").exists());
    let exp_dir = dir.join("exp");
    let poses = dir.join("poses.csv");
    refused(
        dir,
        &[
            "track",
            p(&exp_dir.join("video.avi")),
            "--camera",
            p(&data("camera.json")),
            "--out",
            p(&poses),
            "--tum",
            p(&poses),
        ],
        &["--out", "is the same file as the argument --tum "],
    );
    std::fs::remove_file(&scans_copy).expect("remove");
    // A name of 254 characters works (the temporary name does not grow it).
    let long = dir.join(format!("{}.csv", "p".repeat(250)));
    ok(&[
        "lrf",
        "localize",
        "--map",
        p(&map),
        p(&scans),
        "--out",
        p(&long),
    ]);
    assert!(long.exists());
    // A reference of other times, refused before tracking: no trajectory is left behind.
    let exp = dir.join("exp");
    ok(&[
        "synth",
        "track",
        "--out",
        p(&exp),
        "--frames",
        "20",
        "--seed",
        "3",
    ]);
    let truth = dir.join("other_truth.csv");
    std::fs::write(&truth, "t,x,y,theta,quality\n100,0,0,0,1\n101,0,0,0,1\n").expect("write");
    let traj = dir.join("traj.csv");
    let o = odocal(&[
        "track",
        p(&exp.join("video.avi")),
        "--camera",
        p(&exp.join("camera.json")),
        "--out",
        p(&traj),
        "--truth",
        p(&truth),
    ]);
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("odocal: error: ")
            && err.contains("give the truth of this video in seconds from its first frame"),
        "{err}"
    );
    assert!(
        !traj.exists(),
        "the trajectory of a failed command was left"
    );
    assert!(
        listing(dir).iter().all(|f| !f.ends_with(".tmp")),
        "a temporary file was left: {:?}",
        listing(dir)
    );
    // synth calib with an absurd size: refused before any allocation, no folder made.
    let calib = dir.join("calib");
    refused(
        dir,
        &[
            "synth",
            "calib",
            "--out",
            p(&calib),
            "--width",
            "100000",
            "--height",
            "100000",
        ],
        &["--width 100000", "megapixels"],
    );
    // Too few views to calibrate, and noise no sensor has: refused, nothing written.
    refused(
        dir,
        &["synth", "calib", "--out", p(&calib), "--views", "2"],
        &["--views 2", "at least 3"],
    );
    refused(
        dir,
        &["synth", "calib", "--out", p(&calib), "--noise=-1"],
        &["--noise -1", "0 to 50 grey levels"],
    );
    refused(
        dir,
        &["synth", "track", "--out", p(&calib), "--noise", "500"],
        &["--noise 500", "0 to 50 grey levels"],
    );
}

/// Files of `dir` with a temporary name of odocal (`.odocal-<pid>-<n>.tmp`).
fn temporaries(dir: &Path) -> Vec<String> {
    listing(dir)
        .into_iter()
        .filter(|f| f.starts_with(".odocal-"))
        .collect()
}

#[test]
fn outputs_inside_input_folders_or_naming_folders_are_refused_before_any_work() {
    let d = tempfile::tempdir().expect("tempdir");
    let dir = d.path();
    // A dataset named as a file of train's --report folder: it would be replaced by the report.
    let (exp, sw) = (dir.join("exp"), dir.join("sw"));
    std::fs::create_dir_all(&sw).expect("mkdir");
    experiment_dataset(&exp, &sw.join("report.json"), 12, 1);
    let dataset = std::fs::read(sw.join("report.json")).expect("read");
    for name in ["report.json", "report.md"] {
        let ds = sw.join(name);
        std::fs::write(&ds, &dataset).expect("write");
        let args = [
            "train",
            p(&ds),
            "--sweep",
            "1..1",
            "--restarts",
            "1",
            "--report",
            p(&sw),
        ];
        refused(
            &sw,
            &args,
            &["--report", "is the same file as the argument"],
        );
        assert_eq!(std::fs::read(&ds).expect("read"), dataset);
        std::fs::remove_file(&ds).expect("remove");
    }
    // A file inside a folder the command reads files from: the experiment's truth, a
    // trajectory among --trajectories, a shared view among --shared.
    let truth = exp.join("truth/run001.true.csv");
    let before = std::fs::read(&truth).expect("read");
    let ds = dir.join("ds.json");
    std::fs::write(&ds, &dataset).expect("write");
    for (option, folder) in [
        ("--experiment", &exp),
        ("--trajectories", &exp.join("truth")),
    ] {
        let args = [
            "report",
            "--dataset",
            p(&ds),
            option,
            p(folder),
            "--out",
            p(&truth),
        ];
        refused(
            &exp.join("truth"),
            &args,
            &["--out", "is a file inside", option],
        );
    }
    assert_eq!(std::fs::read(&truth).expect("read"), before);
    let view = exp.join("truth/s00_c0.png");
    std::fs::write(&view, "png").expect("write");
    let args = ["arena", "--camera", "a.json", "b.json", "--shared"];
    let args = [&args[..], &[p(&exp), "--out", p(&view)]].concat();
    refused(&exp, &args, &["--shared", "is a file inside"]);
    // A path ending in a slash names a folder: refused before calibrating, so nothing is
    // replaced and nothing is said to be written.
    let camera = dir.join("camera.json");
    std::fs::write(&camera, "{}").expect("write");
    let ros = format!("{}/ros/", p(dir));
    let o = odocal(&[
        "calibrate",
        "view_0.png",
        "--square",
        "0.05",
        "--out",
        p(&camera),
        "--yaml-opencv",
        p(&dir.join("cam.yaml")),
        "--yaml-ros",
        &ros,
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("ends in a slash"), "{err}");
    assert!(
        o.stdout.is_empty(),
        "{}",
        String::from_utf8_lossy(&o.stdout)
    );
    assert_eq!(std::fs::read(&camera).expect("read"), b"{}");
    assert!(!dir.join("cam.yaml").exists() && temporaries(dir).is_empty());
    let slash = format!("{}/model/", p(dir));
    refused(
        dir,
        &["train", p(&data("dataset.json")), "--out", &slash],
        &["ends in a slash"],
    );
    // A folder no file can be created in is found before training, not after.
    #[cfg(target_os = "linux")]
    refused(
        dir,
        &[
            "train",
            p(&data("dataset.json")),
            "--out",
            "/proc/odocal/m.json",
        ],
        &[
            "--out /proc/odocal/m.json",
            "is in /proc, where devices and processes' files are",
        ],
    );
}

/// `synth` replaces the files of its outputs' names and series in `--out`: a folder of the
/// user's own photos lost `view_07.png` and had `view_00.png` overwritten, exit 0. Outputs
/// that would replace or delete a file of a folder synth did not write are refused, nothing
/// touched; beside other files they are written; a folder synth wrote is replaced.
#[test]
fn synth_refuses_to_replace_files_it_did_not_write() {
    let d = tempfile::tempdir().expect("tempdir");
    let mine = d.path().join("mine");
    std::fs::create_dir_all(&mine).expect("mkdir");
    let own = ["view_00.png", "view_07.png", "map.json"];
    for name in own {
        std::fs::write(mine.join(name), "photo").expect("write");
    }
    let small = [
        "--views",
        "3",
        "--floor-views",
        "0",
        "--width",
        "320",
        "--height",
        "240",
    ];
    let calib = [&["synth", "calib", "--out", p(&mine)][..], &small[..]].concat();
    fails_with(
        &odocal(&calib),
        "the folder holds 2 file(s) synth would replace or delete (view_00.png, view_07.png) and was not written by synth: give a new folder",
    );
    let lrf = ["synth", "lrf", "--out", p(&mine), "--scans", "3"];
    fails_with(
        &odocal(&lrf),
        "holds 1 file(s) synth would replace or delete (map.json)",
    );
    let kept = |dir: &Path| {
        for name in own {
            assert_eq!(std::fs::read(dir.join(name)).expect("kept"), b"photo");
        }
    };
    kept(&mine);
    assert!(!mine.join("truth.json").exists());
    // Outputs of other names are written beside the user's files.
    succeeded(&odocal(&[
        "synth",
        "track",
        "--out",
        p(&mine),
        "--frames",
        "3",
    ]));
    kept(&mine);
    assert!(mine.join("scene.json").exists());
    // A folder synth wrote is written again: fewer views leave none of the earlier ones.
    let again = d.path().join("again");
    let calib = |views: &str| {
        let mut args = vec!["synth", "calib", "--out", p(&again), "--views", views];
        args.extend_from_slice(&small[2..]);
        succeeded(&odocal(&args));
    };
    calib("4");
    calib("3");
    assert!(again.join("view_02.png").exists() && !again.join("view_03.png").exists());
}

/// The OpenCV and ROS YAML files `calibrate` writes for other tools, given back as
/// `--camera`, were refused as "invalid JSON at line 1 column 1"; they are named as what
/// they are, with the file to give instead.
#[test]
fn a_yaml_camera_file_is_named_as_such() {
    let d = tempfile::tempdir().expect("tempdir");
    let opencv = d.path().join("camera-opencv.yaml");
    std::fs::write(
        &opencv,
        "%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\n",
    )
    .expect("write");
    let ros = d.path().join("camera-ros.yaml");
    std::fs::write(
        &ros,
        "image_width: 640\nimage_height: 480\ncamera_name: c\n",
    )
    .expect("write");
    for yaml in [&opencv, &ros] {
        let out = d.path().join("t.csv");
        let o = odocal(&["track", "video.mp4", "--camera", p(yaml), "--out", p(&out)]);
        fails_with(
            &o,
            "is a YAML camera file (OpenCV's or ROS's), which odocal writes for other tools but does not read: pass the camera.json",
        );
    }
}

#[test]
fn an_interrupted_run_leaves_no_temporaries_and_a_killed_ones_are_removed_later() {
    let d = tempfile::tempdir().expect("tempdir");
    let dir = d.path();
    let vids = dir.join("vids");
    let mut child = Command::new(env!("CARGO_BIN_EXE_odocal"))
        .args(["synth", "experiment", "--out", p(&vids), "--runs", "3"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("spawn");
    let start = std::time::Instant::now();
    while temporaries(dir).is_empty() && start.elapsed().as_secs() < 20 {
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    assert!(!temporaries(dir).is_empty(), "no staged folder appeared");
    let pid = child.id().to_string();
    let killed = Command::new("kill").args(["-INT", &pid]).status();
    assert!(killed.expect("kill").success());
    let status = child.wait().expect("wait");
    assert!(!status.success(), "{status:?}");
    assert_eq!(temporaries(dir), Vec::<String>::new(), "left by SIGINT");
    assert!(!vids.exists());
    // Leftovers of a process that is gone (killed with SIGKILL) are removed by the next run
    // writing beside them; those of a live process are not.
    let mut gone = Command::new("true").spawn().expect("spawn");
    let gone_pid = gone.id();
    gone.wait().expect("wait");
    let lrf = dir.join("lrf");
    let stale = lrf.join(format!(".odocal-{gone_pid}-3.tmp"));
    std::fs::create_dir_all(&stale).expect("mkdir");
    std::fs::write(stale.join("frame.png"), "partial").expect("write");
    std::fs::write(lrf.join(format!(".odocal-{gone_pid}-4.tmp")), "x").expect("write");
    let live = format!(".odocal-{}-0.tmp", std::process::id());
    std::fs::write(lrf.join(&live), "x").expect("write");
    ok(&["synth", "lrf", "--scans", "20", "--out", p(&lrf)]);
    assert_eq!(temporaries(&lrf), [live]);
}

#[test]
fn a_closed_stdout_pipe_ends_quietly() {
    let d = tempfile::tempdir().expect("tempdir");
    let mut child = Command::new(env!("CARGO_BIN_EXE_odocal"))
        .args([
            "synth",
            "lrf",
            "--out",
            p(&d.path().join("lrf")),
            "--seed",
            "2",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn");
    drop(child.stdout.take());
    let out = child.wait_with_output().expect("wait");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn a_log_paired_with_another_runs_trajectory_is_rejected_with_its_figures() {
    let d = tempfile::tempdir().expect("tempdir");
    let exp = d.path().join("exp");
    ok(&[
        "synth",
        "experiment",
        "--out",
        p(&exp),
        "--runs",
        "3",
        "--seed",
        "3",
        "--frames",
        "none",
    ]);
    // run002's log (0.5 m/s) with run003's trajectory (0.7 m/s): the speed profiles correlate,
    // the speeds do not.
    let manifest = exp.join("manifest.json");
    let mut m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&manifest).expect("manifest")).expect("json");
    // (run003 itself leaves the manifest: a file listed twice, or a copy of it, is refused
    // before any alignment.)
    m["runs"][1]["trajectory"] = m["runs"][2]["trajectory"].clone();
    if let Some(runs) = m["runs"].as_array_mut() {
        runs.truncate(2);
    }
    std::fs::write(&manifest, m.to_string()).expect("write");
    let out = d.path().join("dataset.json");
    let text = ok(&["dataset", "--manifest", p(&manifest), "--out", p(&out)]);
    assert!(
        text.contains("rejected run002: odometry and camera disagree") && text.contains("m/s RMS"),
        "{text}"
    );
    // A robot file of another logger (0.5 s rows for logs written every 0.2 s) would make
    // every speed and feature wrong by the same factor: refused before any work, naming the log.
    let robot = d.path().join("robot.json");
    std::fs::write(
        &robot,
        r#"{"format":"odocal.robot/1","wheel_diameter_m":0.043,"ticks_per_rev":12,"wheel_base_m":0.1,"period_s":0.5}"#,
    )
    .expect("write");
    let out2 = d.path().join("dataset2.json");
    let e = fails(&[
        "dataset",
        "--manifest",
        p(&manifest),
        "--robot",
        p(&robot),
        "--out",
        p(&out2),
    ]);
    assert!(
        e.contains("run001.odometry.csv: rows are 0.200 s apart")
            && e.contains("logs every 0.500 s"),
        "{e}"
    );
    assert!(!out2.exists());
}

#[test]
fn copies_and_too_few_samples_are_refused_by_train() {
    let d = tempfile::tempdir().expect("tempdir");
    let dir = d.path();
    let ds: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(data("dataset.json")).expect("dataset"))
            .expect("json");
    let one = ds["samples"][0].clone();
    let out = dir.join("model.json");
    for (n, needle) in [(40, "39 of 40 samples are copies"), (1, "1 sample(s)")] {
        let mut v = ds.clone();
        v["samples"] = serde_json::Value::Array(vec![one.clone(); n]);
        let path = dir.join(format!("ds{n}.json"));
        std::fs::write(&path, v.to_string()).expect("write");
        let e = fails(&["train", p(&path), "--out", p(&out)]);
        assert!(
            e.contains(needle) && e.contains(&format!("ds{n}.json")),
            "{e}"
        );
        assert_eq!(e.matches("warning").count(), 0, "{e}");
        assert!(!out.exists());
    }
}

#[test]
fn calibration_refuses_repeated_views_swallowed_views_and_broken_images() {
    let d = tempfile::tempdir().expect("tempdir");
    let dir = d.path();
    let calib = dir.join("calib");
    ok(&[
        "synth",
        "calib",
        "--out",
        p(&calib),
        "--views",
        "4",
        "--floor-views",
        "1",
        "--width",
        "640",
        "--height",
        "480",
        "--seed",
        "5",
    ]);
    let view = calib.join("view_00.png");
    let out = dir.join("camera.json");
    let copies: Vec<PathBuf> = (0..6).map(|i| dir.join(format!("copy_{i}.png"))).collect();
    for c in &copies {
        std::fs::copy(&view, c).expect("copy");
    }
    let mut args = calibrate_args(&out);
    args.extend(copies.iter().map(|c| p(c)));
    refused(
        dir,
        &args,
        &["distinct view", "copy_1.png", "the same view as"],
    );
    // Every file after --floor is a floor image: say so instead of "no views".
    let floor = calib.join("floor_00.png");
    let mut args = calibrate_args(&out);
    args.extend(["--floor", p(&floor), p(&view)]);
    refused(dir, &args, &["--floor took all 2 files"]);
    // A PNG whose header claims 60000 x 60000 pixels, and one cut in half.
    let png = std::fs::read(&view).expect("png");
    let mut huge = png.clone();
    huge[16..20].copy_from_slice(&60000u32.to_be_bytes());
    huge[20..24].copy_from_slice(&60000u32.to_be_bytes());
    let crc = crc32(&huge[12..29]);
    huge[29..33].copy_from_slice(&crc.to_be_bytes());
    let bad_huge = dir.join("huge.png");
    std::fs::write(&bad_huge, &huge).expect("write");
    let bad_cut = dir.join("cut.png");
    std::fs::write(&bad_cut, &png[..png.len() / 2]).expect("write");
    for (bad, needle) in [(&bad_huge, "60000x60000"), (&bad_cut, "damaged PNG")] {
        let views: Vec<PathBuf> = (1..4)
            .map(|i| calib.join(format!("view_{i:02}.png")))
            .collect();
        let mut args = calibrate_args(&out);
        args.push(p(bad));
        args.extend(views.iter().map(|v| p(v)));
        let name = bad.file_name().and_then(|n| n.to_str()).unwrap_or("");
        refused(dir, &args, &[name, needle]);
    }
    // A video given to calibrate, and a trajectory given to track, are named for what they
    // are (an AVI's header stands in for a whole video).
    let avi = dir.join("session.avi");
    std::fs::write(&avi, b"RIFF\x10\0\0\0AVI LIST\0\0\0\0hdrlavih").expect("write");
    let mut args = calibrate_args(&out);
    args.push(p(&avi));
    refused(
        dir,
        &args,
        &["session.avi: is an AVI video, not a photograph", "ffmpeg"],
    );
    let csv = dir.join("robot.csv");
    std::fs::write(&csv, "t,x,y,theta,quality\n0,1,2,0,1\n").expect("write");
    let camera = data("camera.json");
    let t_csv = dir.join("t.csv");
    let track = |video: &Path, extra: &[&str], needles: &[&str]| {
        let mut args = vec![
            "track",
            p(video),
            "--camera",
            p(&camera),
            "--out",
            p(&t_csv),
        ];
        args.extend(extra);
        refused(dir, &args, needles);
    };
    track(
        &csv,
        &[],
        &["robot.csv", "this is a CSV text file, not a video"],
    );
    // A marker below the floor names the option, before any frame is read.
    track(
        &dir.join("none.avi"),
        &["--marker-height=-1"],
        &["--marker-height -1"],
    );
}

/// `odocal calibrate` of a 9x6 board of 5 cm squares into `out`, images to be added.
fn calibrate_args(out: &Path) -> Vec<&str> {
    vec![
        "calibrate",
        "--board",
        "9x6",
        "--square",
        "0.05",
        "--out",
        p(out),
    ]
}

/// CRC-32 of PNG chunks (ISO 3309), to forge a valid header.
fn crc32(bytes: &[u8]) -> u32 {
    let mut c = 0xFFFF_FFFFu32;
    for &b in bytes {
        c ^= u32::from(b);
        for _ in 0..8 {
            c = if c & 1 != 0 {
                0xEDB8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
        }
    }
    !c
}

#[test]
fn a_reflector_lattice_ends_the_map_check_with_a_verdict_not_a_hang() {
    // The search stops at its budget; with congruent configurations already found the verdict
    // is known, and is given with the counts as lower bounds.
    let d = tempfile::tempdir().expect("tempdir");
    let landmarks: Vec<serde_json::Value> = (0..20)
        .flat_map(|i| (0..20).map(move |j| (i, j)))
        .enumerate()
        .map(|(k, (i, j))| serde_json::json!({"id": k + 1, "x_m": i as f64, "y_m": j as f64}))
        .collect();
    let map = serde_json::json!({
        "format": "odocal.lrf-map/1", "reflector_width_m": 0.08, "room_m": [20.0, 20.0],
        "walls": [], "landmarks": landmarks,
    });
    let path = d.path().join("lattice.json");
    std::fs::write(&path, map.to_string()).expect("write");
    let out = odocal(&["lrf", "check-map", p(&path)]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{out:?}");
    for needle in [
        "400 landmarks",
        "congruent sub-configurations (ambiguous for any matcher): at least",
        "the search stopped after 200000 candidate matches",
        "verdict: AMBIGUOUS layout (at least",
    ] {
        assert!(text.contains(needle), "expected {needle:?} in: {text}");
    }
    // A 1 m lattice maps onto itself by whole-metre moves: the largest configurations found
    // are the scanner's whole reach.
    let largest: usize = text
        .lines()
        .find_map(|l| {
            let rest = l.trim().strip_prefix("congruent ")?;
            rest.split_whitespace().next()?.parse().ok()
        })
        .expect("a congruent configuration listed");
    assert!(largest >= 20, "largest configuration {largest}: {text}");
    assert!(String::from_utf8_lossy(&out.stderr).contains("warning"));
}

/// A wrong tag size rejects every frame: `track` names the main reason with its figures, writes
/// `--report` (per-frame decision margins and reprojection errors, not nulls) and no trajectory.
#[test]
fn track_names_why_every_frame_was_rejected_and_still_writes_the_report() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    ok(&["synth", "track", "--out", p(d), "--frames", "8"]);
    let (camera, report, out) = (d.join("camera.json"), d.join("r.json"), d.join("t.csv"));
    let e = fails(&[
        "track",
        p(&d.join("video.avi")),
        "--camera",
        p(&camera),
        "--out",
        p(&out),
        "--report",
        p(&report),
        "--tag-size",
        "0.12",
    ]);
    for needle in [
        "detected but never accepted in 8 frames",
        "8 bad geometry (median corner reprojection",
        "accepted up to 1.5 px",
        "the corners span a square of 80.0 mm on the marker plane (median), -33.3 % from --tag-size 120.0 mm",
        "check first that the camera file is this camera's",
        "only if the tag's black square measures 80.0 mm, give --tag-size 0.0800",
        "per-frame figures in",
    ] {
        assert!(e.contains(needle), "expected {needle:?} in: {e}");
    }
    assert!(!out.exists(), "no trajectory without a fix");
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(r["fixes"], 0);
    let rej = &r["rejections"]["bad geometry"];
    assert_eq!(rej["frames"], 8);
    assert!(
        rej["median_reprojection_px"].as_f64().unwrap() > 1.5,
        "{rej}"
    );
    assert!(
        rej["median_decision_margin"].as_f64().unwrap() > 20.0,
        "{rej}"
    );
    for f in r["per_frame"].as_array().unwrap() {
        assert!(
            f["decision_margin"].is_number() && f["reprojection_px"].is_number(),
            "{f}"
        );
    }
    // Without --report the message says where the figures would be. A size 7.5 % off is
    // refused by the corners' misfit before the size check's ±15 %, and named the same way.
    let e = fails(&[
        "track",
        p(&d.join("video.avi")),
        "--camera",
        p(&camera),
        "--out",
        p(&out),
        "--tag-size",
        "0.086",
    ]);
    assert!(
        e.contains("--report FILE gives the per-frame figures")
            && e.contains("-7.0 % from --tag-size 86.0 mm")
            && e.contains("give --tag-size 0.0800"),
        "{e}"
    );
}

/// `--board 8x6` for a 9x6 board finds an 8x6 part of it, which would move the floor origin
/// by a square: calibrate names the board it sees instead.
#[test]
fn a_board_size_one_corner_short_is_named() {
    let d = tempfile::tempdir().expect("tempdir");
    let dir = d.path();
    let calib = dir.join("calib");
    ok(&[
        "synth",
        "calib",
        "--out",
        p(&calib),
        "--width",
        "640",
        "--height",
        "360",
        "--views",
        "4",
        "--floor-views",
        "1",
        "--seed",
        "7",
    ]);
    let out = dir.join("camera.json");
    // Whether OpenCV finds the 8x6 part of this view (then the board around it is measured)
    // or nothing (then the board found instead is named), the message names the true size.
    let views = [calib.join("view_03.png")];
    let mut args = vec![
        "calibrate",
        "--board",
        "8x6",
        "--square",
        "0.05",
        "--out",
        p(&out),
    ];
    args.extend(views.iter().map(|v| p(v)));
    refused(dir, &args, &["8x6", "9x6 board", "pass --board 9x6"]);
    // --board 6x5 on the 9x6 board: OpenCV takes every other corner along the board for a
    // 6x5 grid, in every view, and the calibration was written with fx 5 times the truth and
    // a floor "within 2 mm". The corners between the ones found name the whole board.
    let mut args = vec![
        "calibrate",
        "--board",
        "6x5",
        "--square",
        "0.05",
        "--out",
        p(&out),
    ];
    let all: Vec<_> = (0..4)
        .map(|k| calib.join(format!("view_{k:02}.png")))
        .collect();
    args.extend(all.iter().map(|v| p(v)));
    refused(dir, &args, &["6x5", "9x6 board", "pass --board 9x6"]);
    // A size OpenCV's classic detector spends 17 s per 1280x720 view failing to find is
    // named from the first view alone, before any view is searched.
    let mut args = vec![
        "calibrate",
        "--board",
        "7x7",
        "--square",
        "0.05",
        "--out",
        p(&out),
    ];
    args.extend(all.iter().map(|v| p(v)));
    refused(
        dir,
        &args,
        &[
            "view_00.png shows a 9x6 board, not the 7x7 of --board",
            "pass --board 9x6",
        ],
    );
    // Far too small a --board: the grid followed from the part found used to stop short
    // (4x3 and 5x3 named "6x6") or run a square past the board (3x3 named "at least 10x6");
    // the sizes around it are now tried with the detector and the board's own is named.
    for small in ["3x3", "4x3", "5x3"] {
        let mut args = vec!["calibrate", "--board", small, "--square", "0.05"];
        args.extend(["--out", p(&out)]);
        args.extend(all.iter().map(|v| p(v)));
        refused(dir, &args, &["shows a 9x6 board", "pass --board 9x6"]);
    }
}

/// `synth calib --blur` is checked like `--noise`: a negative or NaN blur rendered sharp
/// views, and 1e30 allocated memory until killed.
#[test]
fn synth_calib_blur_is_checked() {
    let d = tempfile::tempdir().expect("tempdir");
    for blur in ["-1", "NaN", "1e30"] {
        let e = fails(&[
            "synth",
            "calib",
            "--out",
            p(&d.path().join("c")),
            "--blur",
            blur,
        ]);
        assert!(e.contains("--blur") && e.contains("0 to 20 pixels"), "{e}");
    }
    // A narrow camera whose floor holds no whole board wrote "0 floor views" with exit 0,
    // and its calibration had no floor for `track`.
    let out = d.path().join("c");
    // A 640x360 camera of `hfov` degrees asked for `floor_views` floor views.
    let narrow = |floor_views: &'static str, hfov: &'static str| {
        let mut args = vec!["synth", "calib", "--out", p(&out), "--width", "640"];
        args.extend([
            "--height",
            "360",
            "--views",
            "3",
            "--floor-views",
            floor_views,
        ]);
        args.extend(["--hfov", hfov]);
        odocal(&args)
    };
    let e = fails_with(&narrow("2", "30"), "could place none of the 2 floor views");
    assert!(e.contains("give a wider --hfov"), "{e}");
    assert!(!out.exists(), "{e}");
    // A wide camera's floor squares too small to find were also told "a wider --hfov, a
    // smaller --square", which made it worse; the square asked for then places them all.
    let e = fails_with(&narrow("2", "110"), "could place none of the 2 floor views");
    let at_least = "give a larger --square (at least ";
    assert!(
        e.contains("px a board is found at") && e.contains(at_least),
        "{e}"
    );
    let square = e
        .split(at_least)
        .nth(1)
        .and_then(|r| r.split(' ').next())
        .expect("m");
    let mut args = vec![
        "synth",
        "calib",
        "--out",
        p(&out),
        "--width",
        "640",
        "--height",
    ];
    args.extend(["360", "--views", "3", "--floor-views", "2", "--hfov", "110"]);
    args.extend(["--square", square]);
    let said = ok(&args);
    assert!(said.contains("and 2 floor views"), "{said}");
    std::fs::remove_dir_all(&out).expect("rm");
    // Some placed of more asked for was said only by the count written.
    let run = narrow("5", "35");
    succeeded(&run);
    let said = String::from_utf8_lossy(&run.stderr);
    assert!(
        said.contains("warning: only 4 of the 5 floor views asked for hold a whole board"),
        "{said}"
    );
}

/// The simulated paths are a lab's: a square of 1e300 m ran the simulator until it gave up
/// ("plan 'umbmark-cw' never ended (check gains and speeds)"), a speed of 1e300 m/s wrote
/// squares driven at whatever the motors reached, and a tour area of 1e300 m failed inside
/// the planner. Each is named as the option it is, with the range, and nothing is written.
#[test]
fn synth_paths_beyond_a_lab_and_a_small_robot_are_refused() {
    let d = tempfile::tempdir().expect("tempdir");
    let out = d.path().join("e");
    let experiment = |extra: &[&str], needles: &[&str]| {
        let mut args = vec!["synth", "experiment", "--out", p(&out)];
        args.extend(["--runs", "2", "--frames", "none"]);
        args.extend(extra);
        refused(d.path(), &args, needles);
    };
    for (paths, option, value) in [
        ("umbmark", "--square-m", "1e300"),
        ("umbmark", "--square-m", "25"),
        ("umbmark", "--square-speed", "1e300"),
        ("umbmark", "--square-speed", "6"),
        ("tours", "--tour-area-m", "1e300"),
    ] {
        experiment(
            &["--paths", paths, option, value],
            &[
                &format!("{option} {value}"),
                "at most 20 m",
                "at most 5 m/s",
            ],
        );
    }
    // A speed list in the simulator's file beyond a small robot's is refused the same way.
    let config = d.path().join("fast.json");
    std::fs::write(
        &config,
        r#"{"format": "odocal.robotsim/1", "protocol": {"speeds_mps": [0.5, 50.0]}}"#,
    )
    .unwrap();
    experiment(&["--config", p(&config)], &["speeds_mps", "at most 5 m/s"]);
}

/// ChArUco options are checked before any image is read, and a ChArUco set calibrated with
/// the wrong board or dictionary names what it found instead of calibrating on nonsense.
#[test]
fn charuco_options_and_boards_are_checked() {
    let d = tempfile::tempdir().expect("tempdir");
    let dir = d.path();
    let calib = dir.join("calib");
    ok(&[
        "synth",
        "calib",
        "--target",
        "charuco",
        "--out",
        p(&calib),
        "--views",
        "4",
        "--floor-views",
        "0",
        "--seed",
        "5",
    ]);
    let views: Vec<PathBuf> = (0..4)
        .map(|i| calib.join(format!("view_{i:02}.png")))
        .collect();
    let out = dir.join("camera.json");
    let charuco = |board: &'static str, marker: &'static str, dictionary: &'static str| {
        let mut args = vec![
            "calibrate",
            "--target",
            "charuco",
            "--board",
            board,
            "--square",
            "0.04",
            "--marker",
            marker,
            "--dictionary",
            dictionary,
            "--out",
            p(&out),
        ];
        args.extend(views.iter().map(|v| p(v)));
        args
    };
    for (args, needles) in [
        (
            charuco("11x8", "0.05", "4X4_50"),
            vec!["--marker 0.05", "less than --square 0.04"],
        ),
        (
            charuco("11x8", "0.03", "4X4_51"),
            vec![
                "--dictionary \"4X4_51\"",
                "4X4_50, 4X4_100",
                "APRILTAG_36h11",
            ],
        ),
        (
            charuco("2x8", "0.03", "4X4_50"),
            vec!["at least 3x3 squares"],
        ),
        (
            charuco("14x9", "0.03", "4X4_50"),
            vec!["63 markers", "4X4_50 has only 50"],
        ),
        // The board is one square wider than said: OpenCV numbers the markers row by row, so
        // every row but the first sits elsewhere.
        (
            charuco("12x8", "0.03", "4X4_50"),
            vec![
                "no 12x8 ChArUco board found",
                "do not sit where a 12x8 ChArUco board",
            ],
        ),
        (
            charuco("11x8", "0.03", "5X5_100"),
            vec!["no 5X5_100 marker", "pass --dictionary 4X4_50"],
        ),
    ] {
        refused(dir, &args, &needles);
    }
    let mut args = vec![
        "calibrate",
        "--target",
        "charuco",
        "--board",
        "11x8",
        "--square",
        "0.04",
        "--dictionary",
        "4X4_50",
        "--out",
        p(&out),
    ];
    args.extend(views.iter().map(|v| p(v)));
    refused(dir, &args, &["--target charuco needs --marker"]);
    let mut args = vec![
        "calibrate",
        "--square",
        "0.05",
        "--marker",
        "0.03",
        "--out",
        p(&out),
    ];
    args.extend(views.iter().map(|v| p(v)));
    refused(dir, &args, &["pass --target charuco with them"]);
    // A plain checkerboard's photos given as a ChArUco board's: no marker of any dictionary,
    // and the checkerboard's size is named.
    let plain = dir.join("plain");
    ok(&[
        "synth",
        "calib",
        "--out",
        p(&plain),
        "--views",
        "3",
        "--floor-views",
        "0",
        "--seed",
        "5",
    ]);
    let plain_views: Vec<PathBuf> = (0..3)
        .map(|i| plain.join(format!("view_{i:02}.png")))
        .collect();
    let args = synthetic_charuco_calibration(&out, plain_views.iter().map(|v| p(v)));
    refused(
        dir,
        &args,
        &[
            "shows a plain checkerboard of 9x6 inner corners",
            "leave out --target charuco",
            "pass --board 9x6",
        ],
    );
    refused(
        dir,
        &[
            "synth",
            "calib",
            "--target",
            "charuco",
            "--square",
            "0.04",
            "--marker",
            "0.04",
            "--out",
            p(&dir.join("s")),
        ],
        &["--marker 0.04"],
    );

    // A blank view is skipped as blank; the others calibrate.
    let blank = calib.join("blank.png");
    image::GrayImage::from_pixel(1280, 720, image::Luma([128u8]))
        .save(&blank)
        .expect("write");
    let mut args = charuco("11x8", "0.03", "4X4_50");
    args.push(p(&blank));
    let o = odocal(&args);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("skipped")
            && err.contains("blank.png: the image is uniform (every pixel about 128 of 255)"),
        "{err}"
    );
}

/// Standard output closed before odocal prints its summary (`odocal … | head -1`, quitting
/// `less`): the command still runs to its end and commits its files. A closed pipe used to
/// end the process at the summary line, before its outputs were renamed into place, leaving
/// only a temporary file.
#[test]
fn a_closed_standard_output_loses_no_file() {
    use std::process::{Command, Stdio};
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("lrf");
    let mut child = Command::new(env!("CARGO_BIN_EXE_odocal"))
        .args(["synth", "lrf", "--scans", "20", "--out", p(&out)])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("odocal starts");
    // Close the reading ends at once, as `| true` does.
    drop(child.stdout.take());
    drop(child.stderr.take());
    let status = child.wait().expect("odocal ends");
    assert_eq!(status.code(), Some(0), "{status:?}");
    for f in ["map.json", "scans.csv", "truth.csv"] {
        assert!(
            out.join(f).is_file(),
            "{f} missing: {:?}",
            listing(dir.path())
        );
    }
    assert!(
        listing(dir.path()).iter().all(|f| !f.contains(".tmp")),
        "{:?}",
        listing(dir.path())
    );
}

/// `odocal calibrate` of `views` as `synth calib --target charuco` draws its board (11x8
/// squares of 4 cm, 3 cm 4X4_50 markers), into `out`.
fn synthetic_charuco_calibration<'a>(
    out: &'a Path,
    views: impl IntoIterator<Item = &'a str>,
) -> Vec<&'a str> {
    let mut args = vec![
        "calibrate",
        "--target",
        "charuco",
        "--board",
        "11x8",
        "--square",
        "0.04",
        "--marker",
        "0.03",
        "--dictionary",
        "4X4_50",
        "--out",
        p(out),
    ];
    args.extend(views);
    args
}

/// ChArUco floor views whose markers are too small: at 640x360 (5 px markers) the markers
/// are read, but the corners between them cannot be placed; at 480x320 (4 px) not even the
/// markers are read, though OpenCV finds their outlines. The message used to blame --board
/// and --dictionary, and then to ask for the whole board in sight; it now says how many pixels
/// the markers have and what to change.
#[test]
fn charuco_markers_too_small_are_named_by_their_pixels() {
    let dir = tempfile::tempdir().expect("tempdir");
    for (width, height, said) in [
        (
            "640",
            "360",
            "its markers are 5 px across (median), too few pixels to place the corners",
        ),
        (
            "480",
            "320",
            "could be read: 23 square outlines 4 px across (median) were found, too few pixels to read a marker's cells",
        ),
    ] {
        let d = &dir.path().join(width);
        ok(&[
            "synth",
            "calib",
            "--target",
            "charuco",
            "--width",
            width,
            "--height",
            height,
            "--out",
            p(d),
        ]);
        let images = |prefix: &str| -> Vec<String> {
            let mut v: Vec<String> = listing(d)
                .into_iter()
                .filter(|f| f.starts_with(prefix))
                .map(|f| d.join(f).display().to_string())
                .collect();
            v.sort();
            v
        };
        let (views, floors) = (images("view_"), images("floor_"));
        let out = d.join("camera.json");
        let mut args = synthetic_charuco_calibration(&out, views.iter().map(String::as_str));
        args.push("--floor");
        args.extend(floors.iter().map(String::as_str));
        let e = fails(&args);
        assert!(
            e.contains(said)
                && e.contains("use larger squares and markers")
                && !e.contains("--board counts")
                && !e.contains("whole board in sight"),
            "{width}x{height}: {e}"
        );
        assert!(!out.exists());
    }
}

/// Standard output that cannot be written (a full disk under `> poses.csv`): what was
/// printed is lost, which for some commands is their result, so the command fails with the
/// reason and commits no file. Only a closed pipe is passed over.
#[test]
fn a_standard_output_that_cannot_be_written_fails_the_command() {
    use std::process::{Command, Stdio};
    let Ok(full) = std::fs::OpenOptions::new().write(true).open("/dev/full") else {
        return; // no /dev/full on this system
    };
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("lrf");
    let o = Command::new(env!("CARGO_BIN_EXE_odocal"))
        .args(["synth", "lrf", "--scans", "20", "--out", p(&out)])
        .stdout(Stdio::from(full))
        .output()
        .expect("odocal runs");
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("odocal: error: cannot write to standard output: No space left on device"),
        "{err}"
    );
    assert!(listing(&out).is_empty(), "{:?}", listing(&out));
}
