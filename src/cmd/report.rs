//! `odocal report`: one self-contained HTML file (inline SVG plots, no scripts, no network)
//! from whatever stage outputs are given; sections without inputs are left out with a note.

use std::path::PathBuf;

use anyhow::bail;
use odocal_report::{assemble, ReportInputs};

use crate::output::{
    check_output_dir, check_output_file, check_output_not_in_folder, check_output_not_input,
    commit, write_atomic,
};

/// Arguments of this subcommand.
#[derive(clap::Args)]
pub struct Args {
    /// Where to write the HTML report.
    #[arg(long)]
    pub out: PathBuf,
    /// Output folder of scripts/demo.sh: every input below is looked up there at its standard
    /// place (camera.json, calib/truth.json, experiment/, dataset.json, model.json,
    /// train/report.json, lrf/{poses.csv,truth.csv,map.json}); missing files are left out.
    #[arg(long)]
    pub demo_dir: Option<PathBuf>,
    /// camera.json from `odocal calibrate`.
    #[arg(long)]
    pub camera: Option<PathBuf>,
    /// truth.json from `odocal synth calib` (corner positions for the coverage plot).
    #[arg(long)]
    pub calib_truth: Option<PathBuf>,
    /// dataset.json from `odocal dataset`.
    #[arg(long)]
    pub dataset: Option<PathBuf>,
    /// model.json from `odocal train` (trained on --dataset, when that is given).
    #[arg(long)]
    pub model: Option<PathBuf>,
    /// report.json from `odocal train --sweep A..B --report DIR` (a sweep on --dataset, when
    /// that is given).
    #[arg(long)]
    pub train_report: Option<PathBuf>,
    /// Output folder of `odocal synth experiment` (real tracks: truth/<id>.true.csv or
    /// runs/<id>.trajectory.csv).
    #[arg(long)]
    pub experiment: Option<PathBuf>,
    /// Folder of camera trajectories `<recording id>.trajectory.csv` (from `odocal track`).
    #[arg(long)]
    pub trajectories: Option<PathBuf>,
    /// Sensor poses from `odocal lrf localize --out`.
    #[arg(long)]
    pub lrf_poses: Option<PathBuf>,
    /// True sensor poses (truth.csv from `odocal synth lrf`).
    #[arg(long)]
    pub lrf_truth: Option<PathBuf>,
    /// Landmark map (map.json) to draw the landmarks.
    #[arg(long)]
    pub lrf_map: Option<PathBuf>,
    /// The scanner's range the laser poses were localised with (`lrf localize --max-range-m`),
    /// metres: the map is checked to have the landmarks each pose matched within it.
    #[arg(long, default_value_t = odocal_lrf::SensorConfig::default().max_range_m)]
    pub lrf_max_range_m: f64,
    /// The scanner's field of view the laser poses were localised with (`lrf localize
    /// --fov-deg`), degrees.
    #[arg(long, default_value_t = 240.0)]
    pub lrf_fov_deg: f64,
    /// arena.json from `odocal arena` (draws the cameras' views and overlaps).
    #[arg(long)]
    pub arena: Option<PathBuf>,
    /// The --arena-report of `odocal track --arena` (robots coloured by camera; with --arena).
    #[arg(long, requires = "arena")]
    pub arena_track: Option<PathBuf>,
    /// Track reports of `odocal track --truth … --report` (each a tracking condition: the
    /// report's table of conditions; `--condition` names them). Default with --demo-dir: its
    /// track/report.json.
    #[arg(long, num_args = 1..)]
    pub track_report: Vec<PathBuf>,
    /// Also write every plot as its own SVG file into this folder.
    #[arg(long)]
    pub svg_dir: Option<PathBuf>,
    /// Runs drawn in the trajectory and heading figures (one per commanded speed).
    #[arg(long, default_value_t = 3)]
    pub runs: usize,
    /// Report title.
    #[arg(long, default_value = "odocal report")]
    pub title: String,
}

/// An input: the explicit path (must exist) or the demo folder's standard file (may be absent).
fn input(
    explicit: &Option<PathBuf>,
    demo: &Option<PathBuf>,
    rel: &str,
) -> anyhow::Result<Option<PathBuf>> {
    if let Some(p) = explicit {
        if !p.exists() {
            bail!("{}: no such file or folder", p.display());
        }
        return Ok(Some(p.clone()));
    }
    Ok(demo.as_ref().map(|d| d.join(rel)).filter(|p| p.exists()))
}

/// `path` when it is a folder: a file given where a folder is read would leave its section
/// out as if nothing had been given.
fn folder(path: Option<PathBuf>, option: &str) -> anyhow::Result<Option<PathBuf>> {
    match path {
        Some(p) if !p.is_dir() => bail!(
            "{option} {}: is a file, not a folder (the folder of `odocal synth experiment` or of the trajectories)",
            p.display()
        ),
        p => Ok(p),
    }
}

/// Runs the subcommand.
pub fn run(a: Args) -> anyhow::Result<()> {
    let demo = &a.demo_dir;
    if let Some(d) = demo {
        if !d.is_dir() {
            bail!("--demo-dir {}: no such folder", d.display());
        }
    }
    if !(a.lrf_max_range_m.is_finite() && a.lrf_max_range_m > 0.0) {
        bail!(
            "--lrf-max-range-m {}: need the scanner's range in metres, above 0 (the --max-range-m given to `odocal lrf localize`; default 5.6)",
            a.lrf_max_range_m
        );
    }
    if !(a.lrf_fov_deg > 0.0 && a.lrf_fov_deg <= 360.0) {
        bail!(
            "--lrf-fov-deg {}: need the scanner's field of view in degrees, above 0 and at most 360 (the --fov-deg given to `odocal lrf localize`; default 240)",
            a.lrf_fov_deg
        );
    }
    if a.runs == 0 {
        bail!("--runs 0: the trajectory and heading figures would draw no run; give 1 or more (default 3)");
    }
    // The same track report twice would be two rows of one condition in the table.
    let same_file = |p: &PathBuf| std::fs::canonicalize(p).unwrap_or_else(|_| p.clone());
    let reports: Vec<PathBuf> = a.track_report.iter().map(same_file).collect();
    for (k, r) in a.track_report.iter().enumerate() {
        if reports[..k].contains(&reports[k]) {
            bail!(
                "--track-report {}: given twice; each track report is one tracking condition, give it once",
                r.display()
            );
        }
    }
    let camera = input(&a.camera, demo, "camera.json")?;
    let calib_truth = input(&a.calib_truth, demo, "calib/truth.json")?;
    let dataset = input(&a.dataset, demo, "dataset.json")?;
    let model = input(&a.model, demo, "model.json")?;
    let train_report = input(&a.train_report, demo, "train/report.json")?;
    let experiment = folder(input(&a.experiment, demo, "experiment")?, "--experiment")?;
    let trajectories = folder(
        input(&a.trajectories, demo, "trajectories")?,
        "--trajectories",
    )?;
    if let (Some(t), None) = (&a.calib_truth, &camera) {
        bail!(
            "--calib-truth {}: the coverage plot draws its corners over a calibration: give --camera camera.json too",
            t.display()
        );
    }
    let lrf_poses = input(&a.lrf_poses, demo, "lrf/poses.csv")?;
    let lrf_truth = input(&a.lrf_truth, demo, "lrf/truth.csv")?;
    let lrf_map = input(&a.lrf_map, demo, "lrf/map.json")?;
    // An input that only draws against another, given without it, would be listed among the
    // report's inputs and draw nothing (with the other on hand, it is drawn and checked).
    for (given, option, needs, what) in [
        (
            &a.model,
            "--model",
            dataset.is_some(),
            "--dataset (the dataset.json it was trained on)",
        ),
        (
            &a.experiment,
            "--experiment",
            dataset.is_some(),
            "--dataset (the dataset.json of its runs)",
        ),
        (
            &a.trajectories,
            "--trajectories",
            dataset.is_some(),
            "--dataset (the dataset.json of its runs)",
        ),
        (
            &a.lrf_truth,
            "--lrf-truth",
            lrf_poses.is_some(),
            "--lrf-poses (the poses of `odocal lrf localize`)",
        ),
        (
            &a.lrf_map,
            "--lrf-map",
            lrf_poses.is_some(),
            "--lrf-poses (the poses of `odocal lrf localize`)",
        ),
    ] {
        if let (Some(p), false) = (given, needs) {
            bail!(
                "{option} {}: it is drawn only against {what}, which was not given; give that too, or leave {option} out",
                p.display()
            );
        }
    }

    // The poses given as their own truth agree with themselves to the last digit: a
    // "position RMS 0.0 mm" that judges nothing.
    if let (Some(pp), Some(tp)) = (&lrf_poses, &lrf_truth) {
        if same_file(pp) == same_file(tp) {
            bail!(
                "--lrf-truth {}: is the same file as --lrf-poses, so the poses would be judged against themselves; give the true sensor poses (truth.csv of `odocal synth lrf`, or a motion-capture track)",
                tp.display()
            );
        }
    }
    check_output_file(&a.out, "--out")?;
    // The files found in --demo-dir are not arguments, so the check of --out against the
    // arguments cannot see them (`--demo-dir d --out d/model.json`).
    if let Some(d) = demo {
        let read: Vec<PathBuf> = [
            &camera,
            &calib_truth,
            &dataset,
            &model,
            &train_report,
            &lrf_poses,
            &lrf_truth,
            &lrf_map,
        ]
        .into_iter()
        .flatten()
        .cloned()
        .chain(input(&None, demo, "track/report.json")?)
        .collect();
        let whose = format!("read from --demo-dir {}", d.display());
        check_output_not_input(&a.out, "--out", &read, &whose)?;
    }
    for (folder, whose) in [
        (&experiment, "--experiment"),
        (&trajectories, "--trajectories"),
    ] {
        let folders: Vec<PathBuf> = folder.iter().cloned().collect();
        check_output_not_in_folder(&a.out, "--out", &folders, whose)?;
    }
    if let Some(d) = &a.svg_dir {
        check_output_dir(d, "--svg-dir")?;
    }
    let report = assemble(&ReportInputs {
        camera,
        calib_truth,
        dataset,
        model,
        train_report,
        experiment,
        trajectories,
        lrf_poses,
        lrf_truth,
        lrf_map,
        lrf_max_range_m: Some(a.lrf_max_range_m),
        lrf_fov_deg: Some(a.lrf_fov_deg),
        arena: match input(&a.arena, &None, "")? {
            Some(p) => Some((p, input(&a.arena_track, &None, "")?)),
            None => None,
        },
        // The demo folder's own tracked video (track/report.json) when none are named.
        track_reports: if a.track_report.is_empty() {
            input(&None, demo, "track/report.json")?
                .into_iter()
                .collect()
        } else {
            a.track_report
                .iter()
                .map(|p| input(&Some(p.clone()), &None, ""))
                .collect::<anyhow::Result<Vec<_>>>()?
                .into_iter()
                .flatten()
                .collect()
        },
        runs: a.runs,
        title: a.title.clone(),
    })?;
    // A report of nothing is the wrong folder or no inputs at all: said, not written.
    if report.sections.is_empty() {
        let what = match demo {
            Some(d) => format!(
                "--demo-dir {} holds none of the demo's outputs (camera.json, dataset.json, model.json, train/report.json, lrf/poses.csv, track/report.json, …)",
                d.display()
            ),
            // Inputs that draw only against others were refused alone above.
            None => "no inputs were given".to_string(),
        };
        bail!(
            "nothing to report, so {} was not written: {what}; give the folder `make demo` wrote (--demo-dir demo-out), or the stages' outputs one by one (odocal report --help lists them)",
            a.out.display()
        );
    }
    // A plot's SVG written after the report would replace it (`--out plots/laser-poses.svg
    // --svg-dir plots`), and the report be lost though said written.
    if let Some(dir) = &a.svg_dir {
        let plots: Vec<PathBuf> = report
            .figures()
            .iter()
            .map(|(name, _)| dir.join(format!("{name}.svg")))
            .collect();
        check_output_not_input(
            &a.out,
            "--out",
            &plots,
            &format!("the plot --svg-dir {} writes there", dir.display()),
        )?;
    }
    write_atomic(&a.out, report.to_html().as_bytes())?;
    if let Some(dir) = &a.svg_dir {
        for (name, svg) in report.figures() {
            write_atomic(&dir.join(format!("{name}.svg")), svg.as_bytes())?;
        }
    }
    commit()?;
    let n_fig = report.figures().len();
    say!(
        "report: {} sections, {} plots -> {}{}",
        report.sections.len(),
        n_fig,
        a.out.display(),
        a.svg_dir
            .as_ref()
            .map_or(String::new(), |d| format!(" (SVGs in {})", d.display()))
    );
    for (t, why) in &report.omitted {
        say!("  left out: {t}: {why}");
    }
    // A warning in the page alone is read by whoever opens the page, not by the script that
    // made it.
    for s in &report.sections {
        for b in &s.blocks {
            if let odocal_report::Block::Note(n) = b {
                if let Some(w) = n.strip_prefix("WARNING: ") {
                    tell!("warning: {}: {w}", s.title);
                }
            }
        }
    }
    Ok(())
}
