//! Markdown rendering of a sweep: Table 1 and Table 2 with units stated.

use std::fmt::Write;

use crate::crossval::SweepReport;
use crate::metrics::MeanSd;

fn pm(m: &MeanSd, scale: f64, prec: usize) -> String {
    m.shown(scale, prec)
}

/// Table 1 as Markdown (k, parameters, epochs, training and validation MSE).
pub fn table1_markdown(r: &SweepReport) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "Table 1: hidden size sweep, {}-fold cross-validation x {} restarts (MSE per coordinate in cm²; 1 cm² = 1e-4 m²; {})\n",
        r.settings.folds,
        r.settings.restarts,
        crate::metrics::SPREAD_NOTE
    );
    let _ = writeln!(
        s,
        "| k | parameters (21k+2) | training residuals | epochs | training MSE (cm²) | validation MSE (cm²) | validation rel. error (%) |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|");
    for row in &r.table1 {
        let mark = if row.hidden == r.best_hidden {
            " **best**"
        } else {
            ""
        };
        let _ = writeln!(
            s,
            "| {}{} | {} | {} | {} | {} | {} | {} |",
            row.hidden,
            mark,
            row.n_params,
            row.n_residuals,
            pm(&row.epochs, 1.0, 1),
            pm(&row.train_mse_m2, 1e4, 2),
            pm(&row.val_mse_m2, 1e4, 2),
            pm(&row.val_rel_error, 100.0, 2)
        );
    }
    s
}

/// Table 2 as Markdown (MSE, relative error, dataset size, distance) plus the per-speed breakdown.
pub fn table2_markdown(r: &SweepReport) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "Table 2: cross-validated end-point errors on the same {} folds (MSE per coordinate: m² and cm²; relative error = |error| / path length, mean over runs)\n",
        r.settings.folds
    );
    let _ = writeln!(
        s,
        "| method | MSE (m²) | MSE (cm²) | relative error (%) | RMS end error (cm) | dataset size | mean distance (m) |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|");
    for m in &r.table2 {
        let _ = writeln!(
            s,
            "| {} | {:.6} | {} | {} | {:.2} | {} | {:.3} |",
            m.method,
            m.mse_m2.mean,
            pm(&m.mse_m2, 1e4, 2),
            pm(&m.rel_error, 100.0, 2),
            m.rms_end_error_m * 100.0,
            m.n_samples,
            m.mean_distance_m
        );
    }
    s += &nested_markdown(r);
    let speeds: Vec<f64> = r
        .table2
        .first()
        .map(|m| m.per_speed.iter().map(|p| p.speed_mps).collect())
        .unwrap_or_default();
    if let Some(why) = &r.per_speed_left_out {
        let _ = writeln!(
            s,
            "\nRelative error (%) per commanded speed: left out ({why})."
        );
    } else if !speeds.is_empty() {
        let _ = writeln!(s, "\nRelative error (%) per commanded speed:\n");
        let mut head = String::from("| method |");
        let mut sep = String::from("|---|");
        for (i, v) in speeds.iter().enumerate() {
            let n = r.table2[0].per_speed[i].n;
            let _ = write!(head, " {v:.2} m/s (n={n}) |");
            sep.push_str("---|");
        }
        let _ = writeln!(s, "{head}\n{sep}");
        for m in &r.table2 {
            let mut line = format!("| {} |", m.method);
            for p in &m.per_speed {
                let _ = write!(line, " {:.2} |", 100.0 * p.rel_error);
            }
            let _ = writeln!(s, "{line}");
        }
    }
    s
}

/// What the nested cross-validation chose on each outer fold, as Markdown (empty without it).
fn nested_markdown(r: &SweepReport) -> String {
    let mut s = String::new();
    if r.nested.is_empty() {
        return s;
    }
    let ks: Vec<String> = r.nested.iter().map(|c| c.hidden.to_string()).collect();
    let (what, perceptron) = if r.inner_restarts > 0 {
        (
            format!(
                "the perceptron's hidden size k ({} restart{} per size) and ",
                r.inner_restarts,
                if r.inner_restarts == 1 { "" } else { "s" }
            ),
            format!(
                "Perceptron k per outer fold: {} (Table 1's best k is chosen on the outer folds themselves and is not used in Table 2).",
                ks.join(", ")
            ),
        )
    } else {
        (
            String::new(),
            format!(
                "The perceptron's k is the one size swept, {}.",
                ks.first().map_or("", String::as_str)
            ),
        )
    };
    let _ = writeln!(
        s,
        "\nHyperparameters by nested cross-validation: on each outer fold's training part, an inner {}-fold \
         cross-validation (its folds: the other outer folds) chose {what}kernel ridge's bandwidth and regularisation; \
         the outer fold was then predicted with that choice. {perceptron}\n",
        r.settings.folds - 1,
    );
    let _ = writeln!(
        s,
        "| outer fold | perceptron k | its inner MSE (cm²) | kernel ridge bandwidth (x sqrt(2d), standardised inputs) | kernel ridge lambda | its inner MSE (cm²) |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|");
    for c in &r.nested {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {:.0e} | {:.2} |",
            c.fold + 1,
            c.hidden,
            c.hidden_inner_mse_m2
                .map_or("– (one size)".to_string(), |m| format!("{:.2}", m * 1e4)),
            c.kernel_ridge.bandwidth,
            c.kernel_ridge.lambda,
            c.kernel_ridge_inner_mse_m2 * 1e4
        );
    }
    s
}

/// The whole report as Markdown.
pub fn markdown(r: &SweepReport) -> String {
    let mut s = String::from("# Odometry corrector: cross-validated experiments\n\n");
    let _ = writeln!(
        s,
        "Dataset sha256 `{}`, {} samples; method {:?}, seed {}.\n",
        r.dataset_sha256, r.n_samples, r.settings.train.method, r.settings.seed
    );
    s += &table1_markdown(r);
    s.push('\n');
    s += &table2_markdown(r);
    let k = &r.kinematic_calibration;
    let _ = writeln!(
        s,
        "\nKinematic calibration fitted on all runs: scale {:.4}, curvature {:.4} rad/m, wheel-diameter ratio D_r/D_l {:.4}; \
         ROS diff_drive_controller: left_wheel_radius_multiplier {:.4}, right_wheel_radius_multiplier {:.4}, wheel_separation_multiplier {:.4} \
         (the separation multiplier is weakly determined by straight runs).\n",
        k.scale,
        k.curvature_rad_per_m,
        k.wheel_diameter_ratio,
        k.ros.left_wheel_radius_multiplier,
        k.ros.right_wheel_radius_multiplier,
        k.ros.wheel_separation_multiplier
    );
    let c_b = k.ros.wheel_separation_multiplier;
    if !(0.8..=1.25).contains(&c_b) {
        let _ = writeln!(
            s,
            "Note: the wheel separation multiplier {c_b:.3} is not physically plausible. Straight runs barely determine the \
             wheel base (UMBMark uses square paths with turns); the fit uses it to damp quantised heading noise, and the \
             diameter ratio then compensates (only their quotient, the curvature, is well determined). Do not copy these \
             multipliers into a ROS diff_drive_controller without a calibration run that includes turns.\n"
        );
    }
    let _ = writeln!(s, "**Verdict.** {}\n", r.verdict);
    let _ = writeln!(
        s,
        "Units: MSE is the mean over runs and both coordinates of the squared end-point error (MATLAB's `mse` convention), \
         in m² (cm² = m² x 1e4); the source's objective E = 1/2 ΣΣ(y-t)² equals MSE x 2 x samples. The source does not state \
         its MSE unit, so its 0.165 is not directly comparable."
    );
    if !r.warnings.is_empty() {
        let _ = writeln!(s, "\nWarnings:\n");
        for w in &r.warnings {
            let _ = writeln!(s, "- {w}");
        }
    }
    s
}
