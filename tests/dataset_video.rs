//! The dataset built the way a lab builds it (issue 4): ceiling videos rendered from the
//! simulator's truth, a camera calibrated by `odocal calibrate` from the experiment's own
//! checkerboard views, the videos tracked by `odocal dataset`, and the targets and clock
//! offsets compared with the truth.

mod common;

use common::{fails_with, ok, p, rms};
use odocal_dataset::{Dataset, OracleFile};

#[test]
fn dataset_from_rendered_videos_meets_the_acceptance_bounds() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // Three runs: one at each speed (0.2, 0.5, 0.7 m/s).
    ok(&[
        "synth",
        "experiment",
        "--out",
        p(d),
        "--runs",
        "3",
        "--seed",
        "2",
        "--frames",
        "video",
    ]);
    let views: Vec<String> = (0..20)
        .map(|k| {
            d.join(format!("calib/view_{k:02}.png"))
                .display()
                .to_string()
        })
        .collect();
    let floors: Vec<String> = (0..4)
        .map(|k| {
            d.join(format!("calib/floor_{k:02}.png"))
                .display()
                .to_string()
        })
        .collect();
    let camera = d.join("camera.json");
    let mut args = vec!["calibrate"];
    args.extend(views.iter().map(String::as_str));
    args.extend(["--board", "9x6", "--square", "0.05", "--floor"]);
    args.extend(floors.iter().map(String::as_str));
    args.extend(["--out", p(&camera)]);
    ok(&args);

    let out = d.join("dataset.json");
    ok(&[
        "dataset",
        "--manifest",
        p(&d.join("manifest.json")),
        "--camera",
        p(&camera),
        "--out",
        p(&out),
    ]);
    let ds = Dataset::read(&out).unwrap();
    let oracle = OracleFile::read(&d.join("truth/oracle.json")).unwrap();
    assert_eq!(ds.samples.len(), 3, "rejected: {:?}", ds.rejected);
    let (mut target, mut offset) = (Vec::new(), Vec::new());
    for s in &ds.samples {
        let t = oracle.get(&s.run_id).expect("truth of the run");
        target.push((s.target_m[0] - t.true_end_m[0]).hypot(s.target_m[1] - t.true_end_m[1]));
        offset.push(s.clock_offset_s - t.clock_offset_s);
        assert_eq!(s.inputs.len(), 18);
    }
    println!(
        "targets {:?} mm, clock offsets {:?} ms",
        target.iter().map(|e| e * 1e3).collect::<Vec<_>>(),
        offset.iter().map(|e| e * 1e3).collect::<Vec<_>>()
    );
    assert!(rms(&target) <= 0.0025, "target RMS {} m", rms(&target));
    assert!(rms(&offset) <= 0.005, "clock offset RMS {} s", rms(&offset));
    let rel = ds.summary.raw_relative_error;
    assert!((0.05..=0.13).contains(&rel), "raw relative error {rel}");

    // The tag's options reach the tracker: checked before any video is opened, and a marker
    // height the tags' apparent size contradicts is named (once, with the other runs counted).
    let manifest = d.join("manifest.json");
    let with = |extra: &[&str]| {
        let mut a = vec![
            "dataset",
            "--manifest",
            p(&manifest),
            "--camera",
            p(&camera),
            "--out",
            p(&out),
        ];
        a.extend(extra);
        common::odocal(&a)
    };
    let e = fails_with(&with(&["--tag-size", "0"]), "--tag-size 0");
    assert!(!e.contains("tracking"), "refused before tracking: {e}");
    let res = with(&["--marker-height", "0.15"]);
    let err = String::from_utf8_lossy(&res.stderr);
    assert!(res.status.success(), "{err}");
    // Named in full once, and the other runs counted (a rolling shutter or a wrong height
    // shows in every run: 131 copies would bury everything else).
    assert_eq!(
        err.matches("but --marker-height is 0.150 m").count(),
        1,
        "{err}"
    );
    assert!(
        err.contains("warning: 2 more run(s) gave the warning"),
        "{err}"
    );
}
