//! The trainer's Tables 1 and 2 and the sweep over hidden sizes.

use super::*;

/// Tables 1 and 2 of the trainer's sweep, with the baselines, and the MSE against k.
pub fn training_section(r: &SweepReport) -> Result<Section, ReportError> {
    let mut s = Section::new("training", "Training: Tables 1 and 2");
    s.blocks.push(Block::Text(format!(
        "{} samples, {}-fold cross-validation × {} restarts, seed {}. MSE is per coordinate, in cm² (1 cm² = 1e-4 m²); {}.",
        r.n_samples,
        r.settings.folds,
        r.settings.restarts,
        r.settings.seed,
        odocal_trainer::SPREAD_NOTE
    )));
    let pm = |m: &odocal_trainer::MeanSd, k: f64, p: usize| m.shown(k, p);
    let mut t1 = Table {
        caption: "Table 1: hidden-layer size sweep".into(),
        header: vec![
            "hidden neurons k".into(),
            "parameters".into(),
            "epochs".into(),
            "training MSE (cm²)".into(),
            "validation MSE (cm²)".into(),
            "validation relative error (%)".into(),
        ],
        rows: Vec::new(),
    };
    for row in &r.table1 {
        t1.rows.push(vec![
            if row.hidden == r.best_hidden {
                format!("{} (best)", row.hidden)
            } else {
                row.hidden.to_string()
            },
            row.n_params.to_string(),
            pm(&row.epochs, 1.0, 1),
            pm(&row.train_mse_m2, 1e4, 2),
            pm(&row.val_mse_m2, 1e4, 2),
            pm(&row.val_rel_error, 100.0, 2),
        ]);
    }
    s.blocks.push(Block::Table(t1));
    if !r.table1.is_empty() {
        let k = |f: fn(&odocal_trainer::crossval::Table1Row) -> f64| -> Vec<(f64, f64)> {
            r.table1
                .iter()
                .map(|row| (row.hidden as f64, f(row)))
                .collect()
        };
        let ch = Chart::new(
            "Training and validation MSE against hidden-layer size",
            "hidden neurons k",
            "MSE per coordinate (cm²)",
        )
        .with(Series::new(
            "training MSE",
            k(|r| r.train_mse_m2.mean * 1e4),
            Mark::Line,
            0,
        ))
        .with(Series::new(
            "training MSE",
            k(|r| r.train_mse_m2.mean * 1e4),
            Mark::Markers,
            0,
        ))
        .with(Series::new(
            "validation MSE",
            k(|r| r.val_mse_m2.mean * 1e4),
            Mark::Line,
            1,
        ))
        .with(Series::new(
            "",
            k(|r| r.val_mse_m2.mean * 1e4),
            Mark::Markers,
            1,
        ));
        let mut ch = ch;
        ch.series[1].label.clear();
        s.blocks.push(figure(
            "table1-mse",
            "Mean training and cross-validated MSE per hidden size (cm²): the gap grows when the network over-fits.",
            &ch,
        )?);
    }
    let mut t2 = Table {
        caption: "Table 2: cross-validated end-point errors with baselines".into(),
        header: vec![
            "method".into(),
            "MSE (m²)".into(),
            "MSE (cm²)".into(),
            "relative error (%)".into(),
            "RMS end error (cm)".into(),
            "dataset size (runs)".into(),
            "mean distance (m)".into(),
        ],
        rows: Vec::new(),
    };
    for m in &r.table2 {
        t2.rows.push(vec![
            m.method.clone(),
            format!("{:.6}", m.mse_m2.mean),
            pm(&m.mse_m2, 1e4, 2),
            pm(&m.rel_error, 100.0, 2),
            format!("{:.2}", 100.0 * m.rms_end_error_m),
            m.n_samples.to_string(),
            format!("{:.3}", m.mean_distance_m),
        ]);
    }
    t2.rows.push(vec![
        "reference experiment (reported)".into(),
        "0.165 (unit not stated)".into(),
        "–".into(),
        "3.36 (raw odometry 8–10)".into(),
        "–".into(),
        "131 (161)".into(),
        "≈ 1.5".into(),
    ]);
    s.blocks.push(Block::Table(t2));
    if !r.nested.is_empty() {
        s.blocks.push(Block::Text(format!(
            "Nested cross-validation: on each outer fold's training part an inner {}-fold cross-validation (its folds: the other outer folds) chose {}kernel ridge's bandwidth and regularisation, and the outer fold was predicted with that choice. Table 1's best k is chosen on the outer folds themselves and is not used in Table 2.",
            r.settings.folds - 1,
            if r.inner_restarts > 0 {
                format!(
                    "the perceptron's hidden size k ({} restart{} per size) and ",
                    r.inner_restarts,
                    if r.inner_restarts == 1 { "" } else { "s" }
                )
            } else {
                String::new()
            }
        )));
        s.blocks.push(Block::Table(Table {
            caption: "Hyperparameters chosen by nested cross-validation, per outer fold".into(),
            header: vec![
                "outer fold".into(),
                "perceptron k".into(),
                "its inner MSE (cm²)".into(),
                "kernel ridge bandwidth (× √(2d), standardised inputs)".into(),
                "kernel ridge λ".into(),
                "its inner MSE (cm²)".into(),
            ],
            rows: r
                .nested
                .iter()
                .map(|c| {
                    vec![
                        (c.fold + 1).to_string(),
                        c.hidden.to_string(),
                        c.hidden_inner_mse_m2
                            .map_or("– (one size)".into(), |m| format!("{:.2}", m * 1e4)),
                        c.kernel_ridge.bandwidth.to_string(),
                        format!("{:.0e}", c.kernel_ridge.lambda),
                        format!("{:.2}", c.kernel_ridge_inner_mse_m2 * 1e4),
                    ]
                })
                .collect(),
        }));
    }
    if let Some(why) = &r.per_speed_left_out {
        s.blocks.push(Block::Note(format!(
            "Relative end-point error per commanded speed left out: {why}."
        )));
    }
    if let Some(first) = r.table2.first() {
        if !first.per_speed.is_empty() {
            let mut header = vec!["method".to_string()];
            header.extend(
                first
                    .per_speed
                    .iter()
                    .map(|p| format!("{:.2} m/s (n = {}): rel. error (%)", p.speed_mps, p.n)),
            );
            let rows = r
                .table2
                .iter()
                .map(|m| {
                    let mut v = vec![m.method.clone()];
                    v.extend(
                        m.per_speed
                            .iter()
                            .map(|p| format!("{:.2}", 100.0 * p.rel_error)),
                    );
                    v
                })
                .collect();
            s.blocks.push(Block::Table(Table {
                caption: "Relative end-point error per commanded speed".into(),
                header,
                rows,
            }));
        }
    }
    if !r.verdict.is_empty() {
        s.blocks
            .push(Block::Text(format!("Verdict: {}", r.verdict)));
    }
    for w in &r.warnings {
        s.blocks.push(Block::Note(format!("Trainer warning: {w}")));
    }
    Ok(s)
}

// ---------------------------------------------------------------- laser
