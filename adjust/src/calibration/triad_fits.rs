//! The triad models of a dataset (docs/formats.md 8.4): align's static positions of its
//! multi-position sessions through [`crate::calibration::triad::calibrate`], per session or over all,
//! into calibration.json's `triad` results (or `skipped`, with the reason), and each
//! result's imu_tk `.calib` text. No I/O.

use crate::calibration::triad::{self, Position, TriadModel, TriadSolution};
use ingest::contract::align_ledger::{AlignReport, MultiPosition, StaticPosition};
use ingest::contract::calibration::{
    ALL_SESSIONS, FitScope, GlobalTest, Parameter, PositionFloorUsed, Skipped, TRIAD,
    TriadPosition, TriadResult,
};
use ingest::contract::manifest::{Dataset, ModelDecl, ModelKind, Per};

/// Every triad model of `models` fitted: results and the fits skipped with their reasons.
pub fn fit_all(
    ds: &Dataset,
    models: &[ModelDecl],
    align: &AlignReport,
) -> (Vec<TriadResult>, Vec<Skipped>) {
    let mut results = Vec::new();
    let mut skipped = Vec::new();
    for model in models.iter().filter(|m| m.kind == ModelKind::Triad) {
        let groups: Vec<(FitScope, Vec<&MultiPosition>)> = match model.per {
            Per::Session => align
                .multi_position
                .iter()
                .map(|m| (FitScope::Session(m.session.clone()), vec![m]))
                .collect(),
            Per::All => vec![(FitScope::All, align.multi_position.iter().collect())],
        };
        if align.multi_position.is_empty() {
            skipped.push(skip(
                model,
                ALL_SESSIONS,
                "no multi-position session".to_owned(),
            ));
            continue;
        }
        let kind = TriadModel {
            order: model.order,
            temperature: model.temperature,
        };
        for (scope, group) in groups {
            let all: Vec<(&str, &StaticPosition)> = group
                .iter()
                .flat_map(|m| m.positions.iter().map(|p| (m.session.as_str(), p)))
                .collect();
            // A model with temperature terms leaves out, and counts, the positions the
            // temperature log does not cover; it fails only when none is covered.
            let covered = |p: &StaticPosition| !kind.temperature || p.temperature_c.is_some();
            let total = all.len();
            let rows: Vec<(&str, &StaticPosition)> = if all.iter().any(|(_, p)| covered(p)) {
                all.into_iter().filter(|(_, p)| covered(p)).collect()
            } else {
                all
            };
            let positions: Vec<Position> = rows
                .iter()
                .map(|(_, p)| Position {
                    mean: p.mean,
                    sigma: p.sigma,
                    g_mgal: p.gravity_mgal,
                    temperature_c: p.temperature_c,
                    temperature_sd_c: p.temperature_sd_c,
                })
                .collect();
            match triad::calibrate_with_floor(kind, &positions, model.position_floor) {
                Ok(s) => {
                    let mut r = result(ds, model, scope.id(), &rows, &positions, &s);
                    r.positions_without_temperature = total - rows.len();
                    match r.implausible(&ds.manifest.instrument) {
                        None => results.push(r),
                        Some(reason) => skipped.push(skip(model, scope.id(), reason)),
                    }
                }
                Err(e) => skipped.push(skip(model, scope.id(), e.to_string())),
            }
        }
    }
    (results, skipped)
}

fn skip(model: &ModelDecl, session: &str, reason: String) -> Skipped {
    Skipped {
        accelerometer: TRIAD.to_owned(),
        session: session.to_owned(),
        model: model.name.clone(),
        reason,
    }
}

/// A triad fit's parameters (in `unit`) and their correlation matrix.
fn parameters_of(s: &TriadSolution, unit: &str) -> (Vec<Parameter>, Vec<Vec<f64>>) {
    let names = s.model.names();
    let n = names.len();
    let parameters = names
        .iter()
        .enumerate()
        .map(|(j, name)| Parameter {
            name: (*name).to_owned(),
            unit: unit_of(name, unit),
            value: s.values[j],
            sigma: s.sigma(j),
            sigma_apriori: s.sigma_apriori[j],
            dof: s.floor.and_then(|f| f.interval_mgal).map(|_| s.dof as f64),
        })
        .collect();
    let correlation = (0..n)
        .map(|i| {
            (0..n)
                .map(|j| s.covariance[i * n + j] / (s.sigma(i) * s.sigma(j)))
                .collect()
        })
        .collect();
    (parameters, correlation)
}

fn result(
    ds: &Dataset,
    model: &ModelDecl,
    session: &str,
    rows: &[(&str, &StaticPosition)],
    positions: &[Position],
    s: &TriadSolution,
) -> TriadResult {
    let unit = ds.manifest.instrument.reading_unit.name();
    let (parameters, correlation) = parameters_of(s, unit);
    let (lo, hi, passed) = s.global_test;
    let used: Vec<usize> = s.residuals.iter().map(|r| r.0).collect();
    let range = |values: &mut dyn Iterator<Item = f64>| {
        values.fold([f64::INFINITY, f64::NEG_INFINITY], |[a, b], x| {
            [a.min(x), b.max(x)]
        })
    };
    let readings_range =
        std::array::from_fn(|k| range(&mut used.iter().map(|&i| positions[i].mean[k])));
    let temperature_range_c = s.t_ref_c.map(|_| {
        range(
            &mut used
                .iter()
                .filter_map(|&i| positions[i].temperature_c)
                .flatten(),
        )
    });
    TriadResult {
        model: model.name.clone(),
        session: session.to_owned(),
        reading_unit: unit.to_owned(),
        order: s.model.order,
        temperature: s.model.temperature,
        t_ref_c: s.t_ref_c,
        temperature_range_c,
        temperature_sd_c: s
            .t_ref_c
            .and_then(|_| median_temperature_sd(&used, positions)),
        parameters,
        correlation,
        non_orthogonality_mrad: non_orthogonality(s),
        sigma0: s.sigma0,
        dof: s.dof,
        global_test: GlobalTest {
            statistic: s.vtpv,
            expectation: s.dof as f64,
            dof: s.dof as f64,
            lower: lo,
            upper: hi,
            passed,
        },
        positions_used: s.residuals.len(),
        positions: positions_out(rows, positions, s),
        positions_without_temperature: 0,
        calib_file: calib_file(&model.name, session, s),
        readings_range: Some(readings_range),
        position_floor: s.floor.map(|f| PositionFloorUsed {
            mgal: f.mgal,
            how: if f.interval_mgal.is_some() {
                "estimated"
            } else {
                "declared"
            }
            .to_owned(),
            interval_mgal: f.interval_mgal,
        }),
    }
}

/// Per axis, the median over the positions `used` of their temperatures' sds; none when no
/// position has them.
fn median_temperature_sd(used: &[usize], positions: &[Position]) -> Option<[f64; 3]> {
    let sds: Vec<[f64; 3]> = used
        .iter()
        .filter_map(|&i| positions[i].temperature_sd_c)
        .collect();
    (!sds.is_empty()).then(|| {
        std::array::from_fn(|k| {
            let mut v: Vec<f64> = sds.iter().map(|sd| sd[k]).collect();
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        })
    })
}

/// The imu_tk file a linear triad model is written to. A model the data reject says so in
/// its file's name: imu_tk's layout has no room for a comment, and a user who loads it
/// should not take it for a calibration.
fn calib_file(model: &str, session: &str, s: &TriadSolution) -> Option<String> {
    let (lo, _, passed) = s.global_test;
    // An estimated floor takes up what the positions' own sigmas do not explain: the test
    // then judged those sigmas, not the model with its floor.
    let estimated = s.floor.is_some_and(|f| f.interval_mgal.is_some());
    (s.model == TriadModel::LINEAR).then(|| {
        let rejected = if passed || s.vtpv < lo || estimated {
            ""
        } else {
            "-REJECTED"
        };
        format!("{model}-{session}{rejected}.calib")
    })
}

/// Every position of a triad fit with its residual (the fit's, or the calibrated vector's
/// length against gravity for a removed one), w-test, direction and temperature.
fn positions_out(
    rows: &[(&str, &StaticPosition)],
    positions: &[Position],
    s: &TriadSolution,
) -> Vec<TriadPosition> {
    let removed: Vec<usize> = s.removed.iter().map(|(i, _)| *i).collect();
    rows.iter()
        .enumerate()
        .map(|(i, (session, p))| {
            let a = s.calibrated(&positions[i]);
            let n = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
            let used = s.residuals.iter().find(|r| r.0 == i);
            let (residual_mgal, w) = match used {
                Some(r) => (r.1, r.2),
                None => {
                    let w = s.removed.iter().find(|r| r.0 == i).map_or(0.0, |r| r.1);
                    (n - positions[i].g_mgal, w)
                }
            };
            TriadPosition {
                session: (*session).to_owned(),
                start_gps_ns: p.start_gps_ns,
                residual_mgal,
                w,
                direction: a.map(|x| x / n),
                temperature_c: positions[i].temperature_c,
                removed: removed.contains(&i),
            }
        })
        .collect()
}

/// A parameter's unit from its name's prefix, readings in `unit`.
fn unit_of(name: &str, unit: &str) -> String {
    match name.split('_').next().unwrap_or("") {
        "a" => "rad".to_owned(),
        "s" => format!("mGal/{unit}"),
        "b" => unit.to_owned(),
        "s2" => format!("mGal/{unit}^2"),
        "s3" => format!("mGal/{unit}^3"),
        "bt" => format!("{unit}/K"),
        _ => format!("mGal/{unit}/K"),
    }
}

/// 90 deg minus the angles between the sensitive axes (the rows of T^-1), mrad: xy, xz, yz.
fn departures(angles: [f64; 3]) -> [f64; 3] {
    let [a, b, c] = angles;
    let rows = [[1.0, a, a * c - b], [0.0, 1.0, c], [0.0, 0.0, 1.0]];
    let dep = |i: usize, j: usize| {
        let dot: f64 = (0..3).map(|k| rows[i][k] * rows[j][k]).sum();
        let n = |r: &[f64; 3]| r.iter().map(|x| x * x).sum::<f64>().sqrt();
        (dot / (n(&rows[i]) * n(&rows[j]))).asin() * 1e3
    };
    [dep(0, 1), dep(0, 2), dep(1, 2)]
}

/// The departures from orthogonality with sds propagated through their numerical Jacobian.
fn non_orthogonality(s: &TriadSolution) -> Vec<Parameter> {
    let angles = [s.values[0], s.values[1], s.values[2]];
    let value = departures(angles);
    let mut jac = [[0.0; 3]; 3];
    for k in 0..3 {
        let h = 1e-7;
        let mut up = angles;
        up[k] += h;
        let mut down = angles;
        down[k] -= h;
        let (u, d) = (departures(up), departures(down));
        for r in 0..3 {
            jac[r][k] = (u[r] - d[r]) / (2.0 * h);
        }
    }
    ["xy", "xz", "yz"]
        .iter()
        .enumerate()
        .map(|(r, name)| {
            let var: f64 = (0..3)
                .map(|a| {
                    (0..3)
                        .map(|b| jac[r][a] * s.covariance[a * s.values.len() + b] * jac[r][b])
                        .sum::<f64>()
                })
                .sum();
            Parameter {
                name: (*name).to_owned(),
                unit: "mrad".to_owned(),
                value: value[r],
                sigma: var.max(0.0).sqrt(),
                sigma_apriori: var.max(0.0).sqrt(),
                dof: None,
            }
        })
        .collect()
}

/// imu_tk's `.calib` text: T, K and B whitespace-separated, a blank line after each (what
/// imu_tk's `CalibratedTriad::load` reads). K here is in mGal per reading unit.
pub fn calib_text(r: &TriadResult) -> String {
    let v = |name: &str| {
        r.parameters
            .iter()
            .find(|p| p.name == name)
            .map_or(f64::NAN, |p| p.value)
    };
    let (a_yz, a_zy, a_zx) = (v("a_yz"), v("a_zy"), v("a_zx"));
    let t = [[1.0, -a_yz, a_zy], [0.0, 1.0, -a_zx], [0.0, 0.0, 1.0]];
    let k = [v("s_x"), v("s_y"), v("s_z")];
    let b = [v("b_x"), v("b_y"), v("b_z")];
    let mut out = String::new();
    for row in t {
        out.push_str(&format!(
            "{:.16e} {:.16e} {:.16e}\n",
            row[0], row[1], row[2]
        ));
    }
    out.push('\n');
    for i in 0..3 {
        let row: Vec<String> = (0..3)
            .map(|j| format!("{:.16e}", if i == j { k[i] } else { 0.0 }))
            .collect();
        out.push_str(&row.join(" "));
        out.push('\n');
    }
    out.push('\n');
    for x in b {
        out.push_str(&format!("{x:.16e}\n"));
    }
    out.push('\n');
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn departures_are_the_angles_to_first_order() {
        let d = departures([2e-3, -1.5e-3, 3e-3]);
        assert!((d[0] - 2.0).abs() < 0.01, "{d:?}");
        assert!((d[1] - 1.5).abs() < 0.01, "{d:?}");
        assert!((d[2] - 3.0).abs() < 0.01, "{d:?}");
    }
}
