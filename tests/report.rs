//! End-to-end tests of `odocal report` (issue 7): a report from small synthetic stage outputs,
//! opened in headless Chromium (Debian's `chromium`, installed by `make test`): the screenshot
//! is not blank, every plot has drawn content, and the page logs no script errors.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::{experiment_dataset, fails, ok, p};

fn sorted_files(dir: &Path, prefix: &str) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .expect("read dir")
        .map(|e| e.expect("dir entry").path())
        .filter(|f| {
            f.file_name()
                .is_some_and(|n| n.to_string_lossy().starts_with(prefix))
        })
        .map(|f| f.to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// Every stage's output, small, in the layout of scripts/demo.sh.
fn demo_outputs(d: &Path) {
    let calib = d.join("calib");
    ok(&[
        "synth",
        "calib",
        "--out",
        p(&calib),
        "--seed",
        "3",
        "--width",
        "640",
        "--height",
        "360",
        "--views",
        "8",
        "--floor-views",
        "1",
    ]);
    let mut args: Vec<String> = vec!["calibrate".into()];
    args.extend(sorted_files(&calib, "view_"));
    // The floor view is too small at 640x360 to be found; the report does not need the floor.
    args.extend(["--board", "9x6", "--square", "0.05"].map(String::from));
    args.extend([
        "--out".to_string(),
        d.join("camera.json").to_string_lossy().into_owned(),
    ]);
    ok(&args.iter().map(String::as_str).collect::<Vec<_>>());

    let exp = d.join("experiment");
    let ds = d.join("dataset.json");
    experiment_dataset(&exp, &ds, 24, 2);
    ok(&[
        "train",
        p(&ds),
        "--sweep",
        "2..3",
        "--restarts",
        "1",
        "--folds",
        "3",
        "--report",
        p(&d.join("train")),
    ]);
    ok(&[
        "train",
        p(&ds),
        "--out",
        p(&d.join("model.json")),
        "--hidden",
        "3",
    ]);

    // A tracked video compared with its truth: the table of tracking conditions.
    let track = d.join("track");
    ok(&["synth", "track", "--out", p(&track), "--frames", "12"]);
    ok(&[
        "track",
        p(&track.join("video.avi")),
        "--camera",
        p(&track.join("camera.json")),
        "--out",
        p(&track.join("traj.csv")),
        "--truth",
        p(&track.join("frames.csv")),
        "--report",
        p(&track.join("report.json")),
    ]);

    laser_poses(&d.join("lrf"), "40");
}

/// `odocal synth lrf` (seed 4, `scans` scans) into `lrf`, localised into `lrf/poses.csv`.
fn laser_poses(lrf: &Path, scans: &str) {
    ok(&[
        "synth",
        "lrf",
        "--out",
        p(lrf),
        "--scans",
        scans,
        "--seed",
        "4",
    ]);
    ok(&[
        "lrf",
        "localize",
        "--map",
        p(&lrf.join("map.json")),
        p(&lrf.join("scans.csv")),
        "--out",
        p(&lrf.join("poses.csv")),
    ]);
}

fn chromium() -> PathBuf {
    for name in ["chromium", "chromium-browser"] {
        if let Ok(o) = Command::new("sh")
            .args(["-c", &format!("command -v {name}")])
            .output()
        {
            let s = String::from_utf8_lossy(&o.stdout).trim().to_string();
            if o.status.success() && !s.is_empty() {
                return PathBuf::from(s);
            }
        }
    }
    panic!(
        "chromium is not installed, so the report cannot be checked in a browser: run `make test` \
         (it installs Debian's chromium through scripts/install-deps.sh) or `apt-get install chromium`"
    );
}

/// Runs headless Chromium on `url` with `extra` flags; returns (stdout, stderr).
fn run_chromium(url: &str, extra: &[String]) -> (String, String) {
    let profile = tempfile::tempdir().expect("profile dir");
    let o = Command::new(chromium())
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--disable-dev-shm-usage",
            "--enable-logging=stderr",
            "--v=0",
        ])
        .arg(format!("--user-data-dir={}", profile.path().display()))
        .args(extra)
        .arg(url)
        .output()
        .expect("run chromium");
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "chromium failed: {err}");
    (String::from_utf8_lossy(&o.stdout).into_owned(), err)
}

/// The value of attribute `name` in the start tag `tag`.
fn attr<'a>(tag: &'a str, name: &str) -> Option<&'a str> {
    let key = format!(" {name}=\"");
    let i = tag.find(&key)? + key.len();
    let j = tag[i..].find('"')?;
    Some(&tag[i..i + j])
}

/// Start tags `<name ...>` inside `svg`.
fn tags<'a>(svg: &'a str, name: &str) -> Vec<&'a str> {
    let open = format!("<{name} ");
    let mut out = Vec::new();
    let mut rest = svg;
    while let Some(i) = rest.find(&open) {
        let t = &rest[i..];
        let end = t.find('>').unwrap_or(t.len());
        out.push(&t[..end]);
        rest = &t[end..];
    }
    out
}

/// Checks that an SVG (as the browser serialised it) has drawn data: data lines (stroke width 2)
/// with distinct points or dots, inside the view box, spanning more than a few pixels.
fn check_svg(svg: &str, what: &str) {
    let head = &svg[..svg.find('>').unwrap_or(0)];
    let w: f64 = attr(head, "width")
        .and_then(|v| v.parse().ok())
        .unwrap_or(0.0);
    let h: f64 = attr(head, "height")
        .and_then(|v| v.parse().ok())
        .unwrap_or(0.0);
    assert!(w > 100.0 && h > 100.0, "{what}: svg size {w} x {h}");
    let inside = |x: f64, y: f64| {
        x.is_finite() && y.is_finite() && (0.0..=w).contains(&x) && (0.0..=h).contains(&y)
    };
    let mut pts: Vec<(f64, f64)> = Vec::new();
    for t in tags(svg, "polyline") {
        if attr(t, "stroke-width") != Some("2") {
            continue; // axes and ticks
        }
        let line: Vec<(f64, f64)> = attr(t, "points")
            .unwrap_or("")
            .split_whitespace()
            .filter_map(|xy| {
                let (x, y) = xy.split_once(',')?;
                Some((x.parse().ok()?, y.parse().ok()?))
            })
            .collect();
        assert!(
            line.iter().all(|&(x, y)| inside(x, y)),
            "{what}: line outside the plot: {t}"
        );
        if line.windows(2).any(|p| p[0] != p[1]) {
            pts.extend(line);
        }
    }
    for t in tags(svg, "circle") {
        let x: f64 = attr(t, "cx")
            .and_then(|v| v.parse().ok())
            .unwrap_or(f64::NAN);
        let y: f64 = attr(t, "cy")
            .and_then(|v| v.parse().ok())
            .unwrap_or(f64::NAN);
        assert!(inside(x, y), "{what}: dot outside the plot: {t}");
        pts.push((x, y));
    }
    assert!(!pts.is_empty(), "{what}: no data drawn");
    let span = |f: fn(&(f64, f64)) -> f64| {
        let v: Vec<f64> = pts.iter().map(f).collect();
        v.iter().cloned().fold(f64::MIN, f64::max) - v.iter().cloned().fold(f64::MAX, f64::min)
    };
    assert!(
        span(|p| p.0) > 5.0 || span(|p| p.1) > 5.0,
        "{what}: degenerate data (all within 5 px)"
    );
    // Every plot has a title and axis labels with units.
    let texts = tags(svg, "text").len();
    assert!(
        texts >= 5,
        "{what}: {texts} text elements (title, axis labels, ticks expected)"
    );
    assert!(
        svg.contains('(') && svg.contains(')'),
        "{what}: no unit in the axis labels"
    );
}

fn svgs(html: &str) -> Vec<&str> {
    let mut out = Vec::new();
    let mut rest = html;
    while let Some(i) = rest.find("<svg") {
        let t = &rest[i..];
        let end = t.find("</svg>").map_or(t.len(), |e| e + 6);
        out.push(&t[..end]);
        rest = &t[end..];
    }
    out
}

#[test]
fn report_renders_in_headless_chromium() {
    let browser = chromium(); // fail early and clearly when it is absent
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    demo_outputs(d);
    let html_path = d.join("report.html");
    let svg_dir = d.join("plots");
    let out = ok(&[
        "report",
        "--demo-dir",
        p(d),
        "--out",
        p(&html_path),
        "--svg-dir",
        p(&svg_dir),
    ]);
    assert!(out.contains("report:"), "{out}");
    assert!(
        !out.contains("left out"),
        "every section has inputs here: {out}"
    );

    let html = std::fs::read_to_string(&html_path).expect("report.html");
    // Self-contained: no scripts, nothing loaded from anywhere.
    assert!(!html.contains("<script"), "the report has a script");
    for a in ["src=\"", "href=\"http", "url("] {
        assert!(
            !html.contains(a),
            "the report refers to an external resource ({a})"
        );
    }
    // Every section the issue lists, and every plot also as its own SVG file.
    for id in [
        "calibration",
        "trajectories",
        "heading",
        "corrector",
        "training",
        "laser",
    ] {
        assert!(
            html.contains(&format!("<section id=\"{id}\">")),
            "section {id} missing"
        );
    }
    for fig in [
        "calib-residuals",
        "calib-coverage",
        "calib-projection-uncertainty",
        "errors-x",
        "errors-y",
        "table1-mse",
        "laser-poses",
        "laser-error",
    ] {
        assert!(
            html.contains(&format!("id=\"fig-{fig}\"")),
            "figure {fig} missing"
        );
        assert!(
            svg_dir.join(format!("{fig}.svg")).is_file(),
            "{fig}.svg not written"
        );
    }
    // The coverage plot shows the corners calibrate detected (stored in camera.json), as it
    // would for real photographs, not the synthetic truth's.
    assert!(
        html.contains("corners as detected, from camera.json"),
        "coverage not from the detected corners"
    );
    for fig in ["fig-trajectory-", "fig-heading-"] {
        assert!(
            html.matches(fig).count() >= 3,
            "fewer than 3 {fig} figures (one per speed)"
        );
    }
    for t in ["Table 1", "Table 2", "perceptron", "(cm²)", "(px)", "(mm)"] {
        assert!(html.contains(t), "'{t}' missing from the report");
    }
    let n_svg = svgs(&html).len();
    assert!(n_svg >= 13, "{n_svg} plots");

    // The DOM as the browser built it: every plot parsed and has drawn content; no script errors.
    let url = format!("file://{}", html_path.display());
    let (dom, log) = run_chromium(
        &url,
        &["--dump-dom".into(), "--virtual-time-budget=3000".into()],
    );
    let dom_svgs = svgs(&dom);
    assert_eq!(dom_svgs.len(), n_svg, "the browser's DOM lost plots");
    for (i, s) in dom_svgs.iter().enumerate() {
        check_svg(s, &format!("plot {} of {n_svg}", i + 1));
    }
    for bad in ["Uncaught", "SyntaxError", "TypeError", "ReferenceError"] {
        assert!(!log.contains(bad), "script error in the browser log: {log}");
    }
    assert!(
        log.lines()
            .all(|l| !(l.contains("CONSOLE") && l.contains("ERROR"))),
        "console error: {log}"
    );

    // The screenshot is not blank: enough non-white pixels and real variance.
    let png = d.join("report.png");
    run_chromium(
        &url,
        &[
            format!("--screenshot={}", png.display()),
            "--window-size=1280,4000".into(),
        ],
    );
    let img = image::open(&png).expect("screenshot PNG").to_luma8();
    assert_eq!(img.dimensions(), (1280, 4000));
    let px: Vec<f64> = img.pixels().map(|p| f64::from(p.0[0])).collect();
    let m = px.iter().sum::<f64>() / px.len() as f64;
    let var = px.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / px.len() as f64;
    let ink = px.iter().filter(|v| **v < 200.0).count() as f64 / px.len() as f64;
    assert!(var > 100.0, "screenshot looks blank: variance {var:.1}");
    assert!(
        ink > 0.01,
        "screenshot has {:.2} % dark pixels",
        100.0 * ink
    );
    if let Ok(keep) = std::env::var("ODOCAL_KEEP_REPORT") {
        let _ = std::fs::create_dir_all(&keep);
        let _ = std::fs::copy(&html_path, Path::new(&keep).join("report.html"));
        let _ = std::fs::copy(&png, Path::new(&keep).join("report.png"));
    }
    let _ = browser;
}

/// Sections without their inputs are left out with a note; a report of nothing (no inputs,
/// or a demo folder holding none of the demo's outputs) is refused and nothing is written.
#[test]
fn missing_inputs_are_left_out_with_a_note() {
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    let html = d.join("r.html");
    let e = fails(&["report", "--out", p(&html)]);
    assert!(
        e.contains("nothing to report") && e.contains("no inputs were given"),
        "{e}"
    );
    // Given, but drawing nothing alone: said so, not "no inputs were given".
    let e = fails(&["report", "--out", p(&html), "--experiment", p(d)]);
    assert!(
        e.contains(&format!("--experiment {}: it is drawn only against --dataset (the dataset.json of its runs), which was not given; give that too, or leave --experiment out", p(d))),
        "{e}"
    );
    // Beside another input, a model without its dataset was listed among the inputs and drew
    // nothing, exit 0.
    let model = d.join("stray/model.json");
    std::fs::create_dir_all(d.join("stray")).expect("mkdir");
    std::fs::write(&model, "{}").expect("write");
    let e = fails(&[
        "report",
        "--out",
        p(&html),
        "--model",
        p(&model),
        "--lrf-poses",
        p(&model),
    ]);
    assert!(
        e.contains("it is drawn only against --dataset (the dataset.json it was trained on), which was not given"),
        "{e}"
    );
    let e = fails(&["report", "--demo-dir", p(d), "--out", p(&html)]);
    assert!(e.contains("holds none of the demo's outputs"), "{e}");
    assert!(!html.exists(), "nothing written");
    // One input: its section, and a note for each of the others.
    let lrf = d.join("lrf");
    laser_poses(&lrf, "20");
    let poses = lrf.join("poses.csv");
    // The demo folder's files are inputs though no argument names them.
    let before = std::fs::read(&poses).unwrap();
    let e = fails(&["report", "--demo-dir", p(d), "--out", p(&poses)]);
    assert!(
        e.contains(&format!(
            "(read from --demo-dir {}), which writing it would replace; give --out another path",
            p(d)
        )),
        "{e}"
    );
    assert_eq!(std::fs::read(&poses).unwrap(), before);
    let out = ok(&["report", "--lrf-poses", p(&poses), "--out", p(&html)]);
    assert!(out.contains("report: 1 sections"), "{out}");
    for t in [
        "left out: Camera calibration",
        "(Figures 4–7)",
        "Tables 1 and 2",
        "left out: Laser error against the truth",
    ] {
        assert!(out.contains(t), "no note for {t}: {out}");
    }
    let text = std::fs::read_to_string(&html).expect("html");
    assert!(text.contains("Sections left out"));
    // The laser's truth timed in milliseconds has the time of one pose: the laser section's
    // figures were over it alone, said only in the HTML's small print, exit 0.
    let truth = std::fs::read_to_string(lrf.join("truth.csv")).expect("truth");
    let mut ms = String::new();
    for (i, line) in truth.lines().enumerate() {
        let mut cells: Vec<String> = line.split(',').map(String::from).collect();
        if i > 0 {
            let t: f64 = cells[0].parse().expect("t");
            cells[0] = format!("{}", (t * 1000.0).round());
        }
        ms += &(cells.join(",") + "\n");
    }
    let truth_ms = d.join("truth_ms.csv");
    std::fs::write(&truth_ms, ms).expect("write");
    let bad = d.join("ms.html");
    let e = fails(&[
        "report",
        "--lrf-poses",
        p(&poses),
        "--lrf-truth",
        p(&truth_ms),
        "--out",
        p(&bad),
    ]);
    assert!(
        e.contains("it has the time of only 1 of the")
            && e.contains("timed on one clock, in seconds?"),
        "{e}"
    );
    assert!(!bad.exists());
    ok(&[
        "report",
        "--lrf-poses",
        p(&poses),
        "--lrf-truth",
        p(&lrf.join("truth.csv")),
        "--out",
        p(&bad),
    ]);
    // A file where a folder is read used to leave its section out as if nothing was given.
    for opt in ["--experiment", "--trajectories"] {
        let e = fails(&[
            "report",
            "--lrf-poses",
            p(&poses),
            opt,
            p(&poses),
            "--out",
            p(&d.join("f.html")),
        ]);
        assert!(
            e.contains(opt) && e.contains("is a file, not a folder"),
            "{e}"
        );
    }
    let e = fails(&[
        "report",
        "--calib-truth",
        p(&poses),
        "--out",
        p(&d.join("f.html")),
    ]);
    assert!(e.contains("give --camera camera.json too"), "{e}");
    assert!(!d.join("f.html").exists());
}

#[test]
fn malformed_inputs_are_one_line_errors() {
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    let html = d.join("r.html");
    let bad_json = d.join("dataset.json");
    std::fs::write(
        &bad_json,
        "{\"format\": \"odocal.dataset/1\", \"samples\": [",
    )
    .expect("write");
    let e = fails(&["report", "--out", p(&html), "--dataset", p(&bad_json)]);
    assert!(e.contains("dataset.json"), "{e}");
    let wrong = d.join("report.json");
    std::fs::write(&wrong, "{\"format\": \"odocal.model/1\"}").expect("write");
    let e = fails(&["report", "--out", p(&html), "--train-report", p(&wrong)]);
    assert!(e.contains("odocal.train-report/1"), "{e}");
    let poses = d.join("poses.csv");
    std::fs::write(
        &poses,
        "t,x,y,theta,status,n_landmarks\n0.1,1,2,0.3,ok,4\n0.2,1,x,0.3,ok,4\n",
    )
    .expect("write");
    let e = fails(&["report", "--out", p(&html), "--lrf-poses", p(&poses)]);
    assert!(e.contains("poses.csv:3:"), "{e}");
    let e = fails(&[
        "report",
        "--out",
        p(&html),
        "--camera",
        p(&d.join("nope.json")),
    ]);
    assert!(e.contains("nope.json"), "{e}");
    assert!(!html.exists(), "a failed report must not leave a file");
}

/// A model or sweep report of another dataset than the one given used to be drawn beside its
/// runs as if fitted to them; the report is refused, naming both files and both hashes.
#[test]
fn a_model_or_sweep_of_another_dataset_is_refused() {
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    let (ds, other) = (d.join("dataset.json"), d.join("other.json"));
    experiment_dataset(&d.join("exp"), &ds, 12, 2);
    experiment_dataset(&d.join("exp-other"), &other, 12, 3);
    let (model, sweep) = (d.join("model.json"), d.join("train"));
    ok(&[
        "train",
        p(&ds),
        "--out",
        p(&model),
        "--hidden",
        "3",
        "--no-cv",
    ]);
    ok(&[
        "train",
        p(&ds),
        "--sweep",
        "2..2",
        "--restarts",
        "1",
        "--folds",
        "3",
        "--report",
        p(&sweep),
    ]);
    let sha = |f: &Path| -> String {
        let v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(f).expect("read")).expect("json");
        v["dataset_sha256"]
            .as_str()
            .expect("dataset_sha256")
            .chars()
            .take(12)
            .collect()
    };
    let trained_on = sha(&model);
    assert_eq!(sha(&sweep.join("report.json")), trained_on);
    // The other dataset's hash as train records it, from a model trained on it.
    let other_model = d.join("other-model.json");
    ok(&[
        "train",
        p(&other),
        "--out",
        p(&other_model),
        "--hidden",
        "3",
        "--no-cv",
    ]);
    let other_sha = sha(&other_model);
    assert_ne!(other_sha, trained_on);
    let html = d.join("r.html");
    let e = fails(&[
        "report",
        "--out",
        p(&html),
        "--dataset",
        p(&other),
        "--model",
        p(&model),
    ]);
    assert_eq!(
        e.trim_end(),
        format!(
            "odocal: error: {}: the model was trained on another dataset than {} (its dataset_sha256 {trained_on}…, the dataset's SHA-256 {other_sha}…): its corrections of these runs would be drawn as its fit to them; give the dataset.json it was trained on, or retrain it on this one with `odocal train`",
            p(&model),
            p(&other)
        )
    );
    let report_json = sweep.join("report.json");
    let e = fails(&[
        "report",
        "--out",
        p(&html),
        "--dataset",
        p(&other),
        "--train-report",
        p(&report_json),
    ]);
    assert_eq!(
        e.trim_end(),
        format!(
            "odocal: error: {}: the sweep ran on another dataset than {} (its dataset_sha256 {trained_on}…, the dataset's SHA-256 {other_sha}…): its Tables 1 and 2 would be shown beside runs they were not computed on; give the report.json of a sweep on this dataset, or rerun `odocal train --sweep` on it",
            p(&report_json),
            p(&other)
        )
    );
    assert!(!html.exists(), "nothing written on refusal");
    // `report --out r.html --dataset DS` with `extra`: refused, nothing written; the error.
    let refused_with = |extra: &[&str]| {
        let mut args = vec!["report", "--out", p(&html), "--dataset", p(&ds)];
        args.extend_from_slice(extra);
        let e = fails(&args);
        assert!(!html.exists(), "nothing written on refusal");
        e
    };
    // Another experiment's tracks share the run ids: drawn beside this dataset's odometry,
    // they used to give its heading figure another run's oscillation.
    let other_exp = d.join("exp-other");
    let e = refused_with(&["--experiment", p(&other_exp)]);
    assert!(
        e.contains("its tracks end ")
            && e.contains(
                "mm (median over 3 runs) from the end points the dataset has for the same run ids"
            ),
        "{e}"
    );
    // One run in common is named as one run (it read "median over 1 runs").
    let one = d.join("exp-one");
    std::fs::create_dir_all(one.join("runs")).expect("mkdir");
    std::fs::copy(
        d.join("exp-other/runs/run001.trajectory.csv"),
        one.join("runs/run001.trajectory.csv"),
    )
    .expect("copy");
    let e = refused_with(&["--experiment", p(&one)]);
    assert!(
        e.contains("its track ends ")
            && e.contains("mm from the end point the dataset has for the same run id, where"),
        "{e}"
    );
    // A folder holding no track of the dataset's runs was left out as if not given.
    let empty = d.join("empty");
    std::fs::create_dir_all(&empty).expect("mkdir");
    for option in ["--experiment", "--trajectories"] {
        let e = refused_with(&[option, p(&empty)]);
        assert!(
            e.contains(&format!(
                "{option} {}: it holds the track of none of the",
                p(&empty)
            )) && e.contains("runs drawn from the dataset"),
            "{e}"
        );
    }
    // Given beside the right experiment, another experiment's tracks were left unused and
    // unchecked, exit 0; each folder is checked now.
    let (exp, other_runs) = (d.join("exp"), d.join("exp-other/runs"));
    let e = refused_with(&["--experiment", p(&exp), "--trajectories", p(&other_runs)]);
    assert!(
        e.contains(&format!(
            "--trajectories {}: its tracks end ",
            p(&d.join("exp-other/runs"))
        )),
        "{e}"
    );
    ok(&[
        "report",
        "--out",
        p(&html),
        "--dataset",
        p(&ds),
        "--experiment",
        p(&d.join("exp")),
    ]);
    // The dataset they were made from is reported, and the sweep without it; the model,
    // drawn only against the dataset's runs, is refused without it (it was listed among
    // the inputs and drew nothing).
    ok(&[
        "report",
        "--out",
        p(&html),
        "--dataset",
        p(&ds),
        "--model",
        p(&model),
        "--train-report",
        p(&report_json),
    ]);
    ok(&[
        "report",
        "--out",
        p(&html),
        "--train-report",
        p(&report_json),
    ]);
    let e = fails(&[
        "report",
        "--out",
        p(&html),
        "--model",
        p(&model),
        "--train-report",
        p(&report_json),
    ]);
    assert!(
        e.contains("it is drawn only against --dataset (the dataset.json it was trained on), which was not given; give that too, or leave --model out"),
        "{e}"
    );
}

/// `odocal track --truth frames.csv --report` carries its comparison with the truth into the
/// report's table of tracking conditions; the figures are checked here against the truth.
#[test]
fn tracking_conditions_from_track_reports() {
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    let c = d.join("c");
    ok(&[
        "synth",
        "track",
        "--out",
        p(&c),
        "--frames",
        "30",
        "--seed",
        "4",
        "--speed-min",
        "0.7",
        "--speed-max",
        "0.7",
        "--exposure-ms",
        "10",
        "--rolling-shutter-ms",
        "30",
    ]);
    let (csv, rep) = (d.join("t.csv"), d.join("r.json"));
    let (video, camera) = (c.join("video.avi"), c.join("camera.json"));
    let track = |more: &[&str]| {
        let mut args = vec!["track", p(&video), "--camera", p(&camera), "--out", p(&csv)];
        args.extend_from_slice(more);
        ok(&args)
    };
    let out = track(&[
        "--rolling-shutter-s",
        "0.03",
        "--truth",
        p(&c.join("frames.csv")),
        "--report",
        p(&rep),
        "--condition",
        "10 ms exposure, 30 ms readout",
        "--apriltag3",
    ]);
    assert!(out.contains("error/σ RMS"), "{out}");
    assert!(out.contains("AprilTag 3 alone"), "{out}");
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&rep).expect("report")).expect("json");
    let a = &r["against_truth"];
    assert_eq!(a["condition"], "10 ms exposure, 30 ms readout");
    assert_eq!(a["frames"], 30);
    // The same figure from the files: each fix against the truth at the time its tag was read.
    let truth = std::fs::read_to_string(c.join("frames.csv")).expect("frames.csv");
    let est = std::fs::read_to_string(&csv).expect("trajectory");
    let rows = |t: &str| -> Vec<Vec<f64>> {
        t.lines()
            .skip(1)
            .map(|l| {
                l.split(',')
                    .map(|v| v.parse().unwrap_or(f64::NAN))
                    .collect()
            })
            .collect()
    };
    let truth = rows(&truth);
    let (mut sum, mut n) = (0.0, 0);
    for e in rows(&est) {
        let f = truth
            .iter()
            .find(|f| (f[8] - e[0]).abs() < 1e-4)
            .expect("a truth row at the fix's time");
        sum += (e[1] - f[12]).powi(2) + (e[2] - f[13]).powi(2);
        n += 1;
    }
    let rms = (sum / n as f64).sqrt();
    let reported = a["errors"]["position_rms_m"].as_f64().expect("number");
    assert_eq!(n, 30);
    assert!((rms - reported).abs() < 1e-9, "{rms} vs {reported}");
    assert!(reported < 1e-3, "position RMS {reported} m");
    let z = a["errors"]["error_over_sigma_theta"].as_f64().expect("σ");
    assert!(z > 0.0 && z.is_finite());
    // A sharp, well-lit tag: AprilTag 3 alone finds it in nearly every frame too.
    let at3 = a["apriltag3_rate"].as_f64().expect("AprilTag 3's rate");
    assert!((0.9..=1.0).contains(&at3), "{at3}");

    let html = d.join("r.html");
    let out = ok(&["report", "--track-report", p(&rep), "--out", p(&html)]);
    assert!(out.contains("1 sections"), "{out}");
    let text = std::fs::read_to_string(&html).expect("html");
    assert!(text.contains("Tracking under real-camera conditions"));
    assert!(text.contains("10 ms exposure, 30 ms readout"));
    // The same report twice was two rows of one condition; --runs 0 drew empty figures.
    let again = d.join(".").join("r.json");
    let e = fails(&[
        "report",
        "--track-report",
        p(&rep),
        p(&again),
        "--out",
        p(&html),
    ]);
    assert!(e.contains("given twice"), "{e}");
    let e = fails(&[
        "report",
        "--track-report",
        p(&rep),
        "--runs",
        "0",
        "--out",
        p(&html),
    ]);
    assert!(e.contains("--runs 0"), "{e}");
    // A track report without the truth cannot make a row: one line says what to do.
    let plain = d.join("plain.json");
    track(&["--report", p(&plain)]);
    let e = fails(&["report", "--track-report", p(&plain), "--out", p(&html)]);
    assert!(e.contains("--truth"), "{e}");
}

/// `f` applied to every data row's cells of a CSV file (the header kept), written to `to`.
fn map_csv(from: &Path, to: &Path, f: impl Fn(&mut Vec<String>)) {
    let text = std::fs::read_to_string(from).expect("read csv");
    let mut out = String::new();
    for (i, line) in text.lines().enumerate() {
        let mut cells: Vec<String> = line.split(',').map(String::from).collect();
        if i > 0 {
            f(&mut cells);
        }
        out += &(cells.join(",") + "\n");
    }
    std::fs::write(to, out).expect("write csv");
}

/// `map.json` with every landmark, visibility line and wall moved by (dx, dy) metres.
fn shifted_map(from: &Path, to: &Path, dx: f64, dy: f64) {
    let mut m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(from).expect("read map")).expect("json");
    for l in m["landmarks"].as_array_mut().expect("landmarks") {
        l["x_m"] = serde_json::json!(l["x_m"].as_f64().expect("x") + dx);
        l["y_m"] = serde_json::json!(l["y_m"].as_f64().expect("y") + dy);
        let v = &mut l["visibility_line"];
        if let Some(x) = v["x_m"].as_f64() {
            v["x_m"] = serde_json::json!(x + dx);
        } else if let (Some(a), Some(b)) = (v["a"].as_f64(), v["b"].as_f64()) {
            v["b"] = serde_json::json!(b + dy - a * dx);
        }
    }
    for w in m["walls"].as_array_mut().expect("walls") {
        for (k, d) in [(0, dx), (1, dy), (2, dx), (3, dy)] {
            w[k] = serde_json::json!(w[k].as_f64().expect("wall") + d);
        }
    }
    std::fs::write(to, m.to_string()).expect("write map");
}

/// Laser inputs that drew a misleading section with exit 0 are refused, and nothing written:
/// the report named as a plot's SVG (lost under it), a map of another place (poses drawn 12 m
/// from any landmark they matched), the poses as their own truth ("position RMS 0.0 mm"), a
/// pose log with no pose.
#[test]
fn laser_inputs_that_would_mislead_are_refused() {
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    let lrf = d.join("lrf");
    laser_poses(&lrf, "40");
    let (poses, truth, map) = (
        lrf.join("poses.csv"),
        lrf.join("truth.csv"),
        lrf.join("map.json"),
    );
    let html = d.join("r.html");
    let laser = |extra: &[&str]| {
        let mut a = vec!["report", "--lrf-poses", p(&poses), "--out", p(&html)];
        a.extend_from_slice(extra);
        a.iter().map(|s| s.to_string()).collect::<Vec<_>>()
    };
    let run_fails = |extra: &[&str]| {
        let a = laser(extra);
        let e = fails(&a.iter().map(String::as_str).collect::<Vec<_>>());
        assert!(!html.exists(), "written though refused: {e}");
        e
    };
    // The right map: drawn, with no warning.
    let out = ok(&laser(&["--lrf-map", p(&map), "--lrf-truth", p(&truth)])
        .iter()
        .map(String::as_str)
        .collect::<Vec<_>>());
    assert!(out.contains("report: 1 sections, 2 plots"), "{out}");
    let page = std::fs::read_to_string(&html).expect("html");
    assert!(!page.contains("WARNING"), "a warning over the right map");
    std::fs::remove_file(&html).expect("rm");

    // 8: the report's own path is the laser plot's SVG.
    let plots = d.join("plots");
    let as_plot = plots.join("laser-poses.svg");
    let a = [
        "report",
        "--lrf-poses",
        p(&poses),
        "--lrf-map",
        p(&map),
        "--svg-dir",
        p(&plots),
        "--out",
        p(&as_plot),
    ];
    let e = fails(&a);
    assert!(
        e.contains("the plot --svg-dir") && e.contains("give --out another path"),
        "{e}"
    );
    assert!(!as_plot.exists() && !plots.join("laser-error.svg").exists());

    // 9: the map 20 m off (walls and all, or without walls), and a map of another layout of
    // the same room: every confident pose matched landmarks the map does not have within
    // the scanner's 5.6 m and 240°.
    let far = d.join("far.json");
    shifted_map(&map, &far, 20.0, 0.0);
    let e = run_fails(&["--lrf-map", p(&far)]);
    let n_ok = std::fs::read_to_string(&poses)
        .expect("poses")
        .lines()
        .filter(|l| l.contains(",ok,"))
        .count();
    assert!(
        e.contains(&format!(
            "{n_ok} of the {n_ok} confident laser poses matched more landmarks"
        )) && e.contains("localised against another map or frame"),
        "{e}"
    );
    let other = d.join("other");
    ok(&[
        "synth",
        "lrf",
        "--out",
        p(&other),
        "--scans",
        "2",
        "--seed",
        "3",
    ]);
    let e = run_fails(&["--lrf-map", p(&other.join("map.json"))]);
    assert!(
        e.contains("confident laser poses matched more landmarks"),
        "{e}"
    );
    // The scanner's range is the user's to give: at 2 m the right map has too few.
    let e = run_fails(&["--lrf-map", p(&map), "--lrf-max-range-m", "2"]);
    assert!(e.contains("scanner's range (2 m)"), "{e}");

    // 10: the poses as their own truth, by the same path or a copy.
    let e = run_fails(&["--lrf-truth", p(&poses)]);
    assert!(e.contains("is the same file as --lrf-poses"), "{e}");
    let copy = d.join("copy.csv");
    std::fs::copy(&poses, &copy).expect("copy");
    let e = run_fails(&["--lrf-truth", p(&copy)]);
    assert!(
        e.contains("has the columns status, n_hypotheses, mode of a pose log"),
        "{e}"
    );

    // 13: a header only, and every scan lost.
    let header = d.join("header.csv");
    let text = std::fs::read_to_string(&poses).expect("poses");
    std::fs::write(
        &header,
        format!("{}\n", text.lines().next().expect("header")),
    )
    .expect("w");
    for (file, says) in [
        (header.clone(), "has no scans (a header only)".to_string()),
        (
            d.join("lost.csv"),
            format!("all {} scans are lost", text.lines().count() - 1),
        ),
    ] {
        if !file.exists() {
            map_csv(&poses, &file, |c| {
                for cell in &mut c[1..4] {
                    cell.clear();
                }
                c[4] = "lost".into();
                c[5] = "0".into();
            });
        }
        let e = fails(&["report", "--lrf-poses", p(&file), "--out", p(&html)]);
        assert!(e.contains(&says), "{e}");
        assert!(!html.exists());
    }
}

/// Epoch times and surveyed coordinates gave every tick one label ("1.7e9", "5.4e6"); the
/// same poses 512 345 m east, 5 412 345 m north and 1.7e9 s later are drawn from origins the
/// labels state, with the time since the first scan, and the same error figures.
#[test]
fn laser_plots_of_surveyed_coordinates_and_epoch_times_are_readable() {
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    let lrf = d.join("lrf");
    laser_poses(&lrf, "30");
    let (e0, x0, y0) = (1.7e9, 512_345.0, 5_412_345.0);
    let shift = |c: &mut Vec<String>| {
        let t: f64 = c[0].parse().expect("t");
        c[0] = format!("{:.4}", t + e0);
        if !c[1].is_empty() {
            let x: f64 = c[1].parse().expect("x");
            let y: f64 = c[2].parse().expect("y");
            c[1] = format!("{:.6}", x + x0);
            c[2] = format!("{:.6}", y + y0);
        }
    };
    map_csv(&lrf.join("poses.csv"), &d.join("poses.csv"), shift);
    map_csv(&lrf.join("truth.csv"), &d.join("truth.csv"), shift);
    shifted_map(&lrf.join("map.json"), &d.join("map.json"), x0, y0);
    let report = |dir: &Path, svgs: &Path| {
        ok(&[
            "report",
            "--lrf-poses",
            p(&dir.join("poses.csv")),
            "--lrf-truth",
            p(&dir.join("truth.csv")),
            "--lrf-map",
            p(&dir.join("map.json")),
            "--svg-dir",
            p(svgs),
            "--out",
            p(&svgs.join("r.html")),
        ]);
        let page = std::fs::read_to_string(svgs.join("r.html")).expect("html");
        let at = page.find("position RMS").expect("figure");
        page[at..at + 40].to_string()
    };
    let near = report(&lrf, &d.join("near"));
    let far = report(d, &d.join("far"));
    assert_eq!(near, far, "the error figures moved with the frame");
    let texts = |svg: &Path| -> Vec<String> {
        let s = std::fs::read_to_string(svg).expect("svg");
        s.split("<text")
            .skip(1)
            .filter_map(|t| {
                Some(
                    t.split_once('>')?
                        .1
                        .split_once("</text>")?
                        .0
                        .trim()
                        .to_string(),
                )
            })
            .collect()
    };
    let poses = texts(&d.join("far/laser-poses.svg"));
    assert!(
        poses.contains(&"x, map frame (m) − 512300".to_string()),
        "{poses:?}"
    );
    assert!(
        poses.contains(&"y, map frame (m) − 5412300".to_string()),
        "{poses:?}"
    );
    let err = texts(&d.join("far/laser-error.svg"));
    assert!(
        err.contains(&"time since the first scan (s)".to_string()),
        "{err:?}"
    );
    for t in poses.iter().chain(&err) {
        assert!(
            !t.contains("e5") && !t.contains("e6") && !t.contains("e9"),
            "tick {t}"
        );
    }
    // The scans are 0.1 s apart: 3 s of them have ticks 0 to 3 s.
    assert!(
        err.contains(&"0".to_string()) && err.contains(&"2".to_string()),
        "{err:?}"
    );
}

/// Half a million poses made a 96 MB page of a million dots; the plots draw at most 5000 per
/// series, say so, and the figures are still over all of them.
#[test]
fn laser_plots_of_many_poses_are_thinned_and_say_so() {
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    let lrf = d.join("lrf");
    laser_poses(&lrf, "20");
    let poses = std::fs::read_to_string(lrf.join("poses.csv")).expect("poses");
    let truth = std::fs::read_to_string(lrf.join("truth.csv")).expect("truth");
    // The 20 scans over and over: 60 000 poses, 0.1 s apart.
    let n = 60_000;
    let repeat = |text: &str| {
        let mut lines = text.lines();
        let mut out = format!("{}\n", lines.next().expect("header"));
        let rows: Vec<&str> = lines.collect();
        for k in 0..n {
            let row = rows[k % rows.len()];
            let rest = row.split_once(',').expect("row").1;
            out += &format!("{:.1},{rest}\n", k as f64 * 0.1);
        }
        out
    };
    std::fs::write(d.join("poses.csv"), repeat(&poses)).expect("w");
    std::fs::write(d.join("truth.csv"), repeat(&truth)).expect("w");
    let html = d.join("r.html");
    let small = d.join("small.html");
    for (dir, out) in [(d, &html), (lrf.as_path(), &small)] {
        ok(&[
            "report",
            "--lrf-poses",
            p(&dir.join("poses.csv")),
            "--lrf-truth",
            p(&dir.join("truth.csv")),
            "--out",
            p(out),
        ]);
    }
    let page = std::fs::read_to_string(&html).expect("html");
    let n_ok = repeat(&poses)
        .lines()
        .filter(|l| l.contains(",ok,"))
        .count();
    let dots = page.matches("<circle").count();
    assert!(dots <= 3 * 5000 + 20, "{dots} dots");
    assert!(page.len() < 3_000_000, "{} bytes", page.len());
    let step = n_ok.div_ceil(5000);
    assert!(
        page.contains(&format!("of the {n_ok} ok estimates"))
            && page.contains(&format!(
                "the largest error of every {step} consecutive ok scans ({n_ok} in all)"
            )),
        "no caption of the thinning"
    );
    // The figures are over every pose: those of the 20 scans, which repeat.
    let figure = |page: &str| {
        let at = page.find("position RMS").expect("figure");
        page[at..at + 40].to_string()
    };
    let small_page = std::fs::read_to_string(&small).expect("html");
    assert_eq!(figure(&page), figure(&small_page));
    assert!(
        page.contains(&format!("{n} scans: {n_ok} ok")),
        "not over all poses"
    );
    assert!(!small_page.contains("Drawn:"), "a small input said thinned");
}

/// A known camera's file (synth calib's camera_true.json) given as --camera made a
/// calibration section "from 0 views: reprojection RMS 0.000 px", exit 0; it is refused.
#[test]
fn a_known_camera_is_not_taken_for_a_calibration() {
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    let calib = d.join("calib");
    ok(&[
        "synth",
        "calib",
        "--out",
        p(&calib),
        "--views",
        "3",
        "--floor-views",
        "0",
        "--width",
        "320",
        "--height",
        "240",
    ]);
    let html = d.join("r.html");
    let e = fails(&[
        "report",
        "--camera",
        p(&calib.join("camera_true.json")),
        "--out",
        p(&html),
    ]);
    assert!(
        e.contains("has no calibration views (reprojection RMS 0 px from none)")
            && e.contains("give the camera.json `odocal calibrate` wrote"),
        "{e}"
    );
    assert!(!html.exists());
}

/// Trajectory files of the runs that reach no run's end (cut to one pose) were reported as
/// a folder holding "the track of none of the runs", looked for under names it had.
#[test]
fn trajectories_cut_short_are_named_as_found() {
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    let (exp, ds) = (d.join("exp"), d.join("dataset.json"));
    experiment_dataset(&exp, &ds, 6, 2);
    let cut = d.join("cut");
    std::fs::create_dir_all(&cut).expect("mkdir");
    let runs = sorted_files(&exp.join("runs"), "run");
    let mut n = 0;
    for f in runs.iter().filter(|f| f.ends_with(".trajectory.csv")) {
        let text = std::fs::read_to_string(f).expect("read");
        let first_two: Vec<&str> = text.lines().take(2).collect();
        let name = Path::new(f).file_name().expect("name");
        std::fs::write(cut.join(name), first_two.join("\n") + "\n").expect("write");
        n += 1;
    }
    assert!(n >= 3, "{n} trajectories");
    let html = d.join("r.html");
    let e = fails(&[
        "report",
        "--dataset",
        p(&ds),
        "--trajectories",
        p(&cut),
        "--out",
        p(&html),
    ]);
    assert!(
        e.contains("it has the tracks of 3 of the 3 runs drawn from the dataset, but none reaches its run's end"),
        "{e}"
    );
    assert!(!html.exists());
    // The whole tracks are drawn.
    let out = ok(&[
        "report",
        "--dataset",
        p(&ds),
        "--trajectories",
        p(&exp.join("runs")),
        "--out",
        p(&html),
    ]);
    assert!(out.contains("report: 3 sections"), "{out}");
}
