//! End-point errors across runs: odometry's against the real end points, and the corrector's estimate of them.

use super::*;

/// Figures 6–7: the end-point errors of odometry across runs and the corrector's estimate.
pub fn corrector_section(
    samples: &[Sample],
    predicted_m: Option<&[[f64; 2]]>,
) -> Result<Section, ReportError> {
    let mut s = Section::new(
        "corrector",
        "End-point errors across runs (Figures 6 and 7)",
    );
    s.blocks.push(Block::Text(
        "Odometry error = real end − raw odometry end, per run, in the run's start frame (cm). The corrector's estimate of it = its corrected end − raw odometry end. The model was trained on all runs, so this is its fit, not a held-out test (Table 2 gives the cross-validated figures).".into(),
    ));
    if predicted_m.is_none() {
        s.blocks.push(Block::Note(
            "No model was given (--model): only the odometry errors are drawn.".into(),
        ));
    }
    for (axis, i, fig) in [("x", 0usize, 6), ("y", 1usize, 7)] {
        let real: Vec<(f64, f64)> = samples
            .iter()
            .enumerate()
            .map(|(k, sm)| ((k + 1) as f64, 100.0 * (sm.target_m[i] - sm.raw_end_m[i])))
            .collect();
        let mut ch = Chart::new(
            &format!("Figure {fig}: {axis} error of the end point across runs"),
            "run index",
            &format!("{axis} error (cm)"),
        )
        .with(Series::new("real − odometry (target)", real, Mark::Line, 6));
        if let Some(p) = predicted_m {
            ch.series.push(Series::new(
                "corrector − odometry (predicted)",
                samples
                    .iter()
                    .zip(p)
                    .enumerate()
                    .map(|(k, (sm, e))| ((k + 1) as f64, 100.0 * (e[i] - sm.raw_end_m[i])))
                    .collect(),
                Mark::Line,
                1,
            ));
        }
        s.blocks.push(figure(
            &format!("errors-{axis}"),
            &format!("The {axis} component of the end-point error per run (cm): target and the corrector's approximation."),
            &ch,
        )?);
    }
    let mut t = Table {
        caption: "End-point errors over all runs (in-sample)".into(),
        header: vec![
            "estimate".into(),
            "runs".into(),
            "MSE per coordinate (cm²)".into(),
            "RMS end error (cm)".into(),
            "mean relative error (% of path length)".into(),
        ],
        rows: Vec::new(),
    };
    let mut row = |name: &str, ends: Vec<[f64; 2]>| {
        let d: Vec<f64> = samples
            .iter()
            .zip(&ends)
            .map(|(sm, e)| (e[0] - sm.target_m[0]).hypot(e[1] - sm.target_m[1]))
            .collect();
        let rel: Vec<f64> = samples
            .iter()
            .zip(&d)
            .map(|(sm, e)| e / sm.path_length_m.max(1e-9))
            .collect();
        let mse = d.iter().map(|e| e * e).sum::<f64>() / (2.0 * d.len().max(1) as f64);
        t.rows.push(vec![
            name.to_string(),
            d.len().to_string(),
            format!("{:.2}", mse * 1e4),
            format!("{:.2}", 100.0 * rms(&d)),
            format!("{:.2}", 100.0 * mean(&rel)),
        ]);
    };
    row(
        "raw odometry",
        samples.iter().map(|s| s.raw_end_m).collect(),
    );
    if let Some(p) = predicted_m {
        row("corrected (model)", p.to_vec());
    }
    s.blocks.push(Block::Table(t));
    Ok(s)
}

// ---------------------------------------------------------------- training
