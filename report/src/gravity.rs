//! The report's section on a survey reduced to gravity (docs/formats.md 10), when OUT holds
//! the gravity stage's outputs for this dataset: what was reduced and dropped, the ties and
//! drift of each stretch, the disturbance's range and sigma with its parts (north and east
//! too where a session gives attitude), the crossovers, the track on a map coloured by the
//! filtered disturbance and the profile along the track with its 1-sigma band.

use crate::Error;
use crate::plots;
use crate::render::{Section, Table, section};
use ingest::contract::gravity_ledger::{GravityReport, LEDGER_FILE, STAGE_DIR};
use ingest::contract::manifest::Dataset;
use ingest::contract::tables::{attitude, gravity};
use std::path::Path;

/// The epochs as the section draws them.
struct Epoch {
    session: u16,
    time_ns: i64,
    lat: f64,
    lon: f64,
    filtered: f64,
    sigma: f64,
    parts: [f64; 6],
}

/// Most points a plot draws (every k-th epoch beyond).
const MAX_POINTS: usize = 1500;

/// The section's title; a report that opens on it is a survey report.
pub(crate) const TITLE: &str = "Gravity along the track";

/// What the stage's value down is (docs/formats.md 10.3): gravity less normal gravity at the
/// trajectory's heights, the disturbance above the ellipsoid and the free-air anomaly above
/// sea level; where sessions differ, said as that.
fn quantity(r: &GravityReport) -> &'static str {
    let mut heights = r.sessions.iter().map(|s| s.quantities.heights);
    match heights.next() {
        Some(first) if heights.all(|h| h == first) => match first {
            ingest::contract::survey::Heights::Ellipsoidal => "gravity disturbance down",
            ingest::contract::survey::Heights::SeaLevel => "free-air anomaly",
        },
        _ => "gravity less normal gravity at the trajectory's heights",
    }
}

/// The result in one paragraph, first: the filtered values' range and median sigma, the
/// ties and drift, the crossovers.
fn answer(r: &GravityReport, epochs: &[Epoch]) -> String {
    let mut values: Vec<f64> = epochs
        .iter()
        .map(|e| e.filtered)
        .filter(|v| v.is_finite())
        .collect();
    let mut sigmas: Vec<f64> = epochs
        .iter()
        .map(|e| e.sigma)
        .filter(|v| v.is_finite())
        .collect();
    values.sort_by(f64::total_cmp);
    sigmas.sort_by(f64::total_cmp);
    let used: u64 = r.sessions.iter().map(|s| s.epochs_used).sum();
    let range = match (values.first(), values.last(), sigmas.get(sigmas.len() / 2)) {
        (Some(lo), Some(hi), Some(m)) => format!(
            "the filtered {} from {lo:.2} to {hi:.2} mGal, median sigma {m:.2} mGal",
            quantity(r)
        ),
        _ => "no filtered value (every epoch within a filter period of its stretch's ends)"
            .to_owned(),
    };
    let used_ties = r.ties.iter().filter(|t| t.used_in.is_some()).count();
    let drifts: Vec<String> = r
        .sessions
        .iter()
        .filter_map(|s| {
            let d = s.stretches.iter().find_map(|st| st.drift.as_ref())?;
            let drift = match d.sigma_rate_mgal_per_h {
                Some(sd) => format!("drift {:.3} ± {sd:.3} mGal/h", d.rate_mgal_per_h),
                None => "no drift (one tie)".to_owned(),
            };
            Some(format!(
                "{}: offset {:.2} ± {:.2} mGal, {drift}",
                s.id, d.offset_mgal, d.sigma_offset_mgal
            ))
        })
        .collect();
    let ties = match (r.ties.len(), drifts.is_empty()) {
        (0, _) => "no tie: values at the calibration's level".to_owned(),
        (_, true) => format!("{} tie(s), none used", r.ties.len()),
        (n, false) => format!("{used_ties} of {n} tie(s) used ({})", drifts.join("; ")),
    };
    let n = r.crossovers.len();
    let crossovers = if n == 0 {
        "no crossover".to_owned()
    } else {
        let rms = |f: &dyn Fn(&ingest::contract::gravity_ledger::Crossover) -> f64| {
            (r.crossovers.iter().map(|c| f(c).powi(2)).sum::<f64>() / n as f64).sqrt()
        };
        format!(
            "{n} crossover(s), rms difference {:.3} mGal, rms difference / sigma {:.2}",
            rms(&|c| c.difference_mgal),
            rms(&|c| c.difference_mgal / c.sigma_mgal)
        )
    };
    format!("{used} epochs reduced: {range}; {ties}; {crossovers}.")
}

/// The section, or None when OUT holds no gravity stage output.
pub(crate) fn gravity_section(ds: &Dataset, out: &Path) -> Result<Option<Section>, Error> {
    let dir = out.join(STAGE_DIR);
    let ledger = dir.join(LEDGER_FILE);
    if !ledger.exists() {
        return Ok(None);
    }
    let r: GravityReport = ingest::read_json(&ledger)?;
    ingest::contract::custody::check_dataset(&ledger, &r.dataset, &ds.manifest.name)?;
    let table = dir.join(gravity::FILE);
    recorded(&table, &r.sha256)?;
    let epochs = read(&table)?;
    let mut s = section(TITLE);
    s.text.push(answer(&r, &epochs));
    s.text.push(summary(&r));
    for n in &r.not_reduced {
        s.text
            .push(format!("Session {} was not reduced: {}.", n.session, n.why));
    }
    s.tables.push(("What was reduced".to_owned(), reduced(&r)));
    s.tables
        .push(("Ties and drift, per stretch".to_owned(), ties(&r)));
    s.tables.push((
        format!(
            "The filtered {} and its sigma (mGal; the sigma's parts are medians)",
            quantity(&r)
        ),
        disturbance(ds, &epochs),
    ));
    if let Some(t) = horizontal(ds, &table)? {
        s.tables.push((
            "With attitude: the filtered disturbance north and east and their sigma (mGal; \
             the sigma's parts are medians; never tied)"
                .to_owned(),
            t,
        ));
    }
    if let Some(t) = estimated_positions(&r) {
        s.tables.push((
            "Antennas' positions estimated from the data (vehicle frame, from the \
             accelerometers; docs/formats.md 10.2.1)"
                .to_owned(),
            t,
        ));
    }
    s.tables.push((
        "Crossovers: where the track crosses itself (mGal)".to_owned(),
        crossovers(&r),
    ));
    s.plots.extend(plots(&epochs, quantity(&r))?);
    if let Some((_, sha256)) = &r.attitude_table {
        s.plots
            .extend(attitude_plots(&dir.join(attitude::FILE), sha256)?);
    }
    Ok(Some(s))
}

/// The table at `path` is the one gravity.json recorded (its SHA-256), or it is named stale.
fn recorded(path: &Path, sha256: &str) -> Result<(), Error> {
    if ingest::contract::custody::sha256_file(path)? != sha256 {
        return Err(ingest::Error::Stale {
            path: path.to_path_buf(),
            message: "is not the table gravity.json recorded: re-run `cargo xtask gravity`"
                .to_owned(),
        }
        .into());
    }
    Ok(())
}

/// One row of attitude.parquet: its time (ns) and, per angle, its value and sd in deg (None
/// where null).
type AttitudeRow = (i64, [Option<(f64, f64)>; 3]);

/// An antenna array's attitude (attitude.parquet, the one gravity.json recorded): per
/// session and angle, the angle against time with its 1-sigma band; an angle the array does
/// not give (two antennas' roll, null throughout) has no plot.
fn attitude_plots(path: &Path, sha256: &str) -> Result<Vec<(String, String)>, Error> {
    use arrow_array::Array;
    recorded(path, sha256)?;
    let mut rows: std::collections::BTreeMap<u16, Vec<AttitudeRow>> =
        std::collections::BTreeMap::new();
    ingest::contract::tables::float_batches_unflagged(
        path,
        &attitude::FLOATS[..6],
        1 << 16,
        |b| {
            for i in 0..b.time_ns.len() {
                let angle = |j: usize| {
                    let (v, sd) = (b.values[j], b.values[j + 3]);
                    (v.is_valid(i) && sd.is_valid(i)).then(|| (v.value(i), sd.value(i)))
                };
                let row = (b.time_ns[i], [angle(0), angle(1), angle(2)]);
                rows.entry(b.session[i]).or_default().push(row);
            }
            Ok(())
        },
    )?;
    let mut out = Vec::new();
    for (index, r) in rows {
        let step = r.len().div_ceil(MAX_POINTS).max(1);
        let t0 = r[0].0;
        for (j, name) in ["heading", "pitch", "roll"].into_iter().enumerate() {
            let points: Vec<(f64, f64, f64)> = r
                .iter()
                .step_by(step)
                .filter_map(|(t, a)| a[j].map(|(v, sd)| ((t - t0) as f64 / 60e9, v, sd)))
                .collect();
            if points.is_empty() {
                continue;
            }
            out.push(band_plot(
                format!("attitude_{name}_{index}.svg"),
                (&format!("The antennas' {name}"), name, "deg"),
                ("minutes from the session's first epoch", name),
                &[points],
            )?);
        }
    }
    Ok(out)
}

/// Each crossover's two passes, the difference against its sigma; then their rms and the
/// rms of difference over sigma (near 1 when the sigmas are honest), or a row saying the
/// track does not cross itself.
fn crossovers(r: &GravityReport) -> Table {
    let mut t = Table::headed(
        "where (lat, lon) | first pass | second pass | angle (deg) | difference | sigma | difference / sigma",
    );
    let pass = |p: &ingest::contract::gravity_ledger::Pass| {
        format!(
            "{} {} #{}: {:.3} ± {:.3}",
            p.session, p.time, p.stretch, p.filtered_mgal, p.sigma_mgal
        )
    };
    for c in &r.crossovers {
        t.rows.push(vec![
            format!("{:.5}, {:.5}", c.latitude_deg, c.longitude_deg),
            pass(&c.first),
            pass(&c.second),
            format!("{:.0}", c.angle_deg),
            format!("{:+.3}", c.difference_mgal),
            format!("{:.3}", c.sigma_mgal),
            format!("{:+.2}", c.difference_mgal / c.sigma_mgal),
        ]);
    }
    let n = r.crossovers.len();
    let mut last = vec![String::new(); 7];
    if n == 0 {
        last[0] = "none: the track does not cross itself where it may be compared \
                   (moving, not turning, not near a stretch's end)"
            .to_owned();
    } else {
        let rms = |f: &dyn Fn(&ingest::contract::gravity_ledger::Crossover) -> f64| {
            (r.crossovers.iter().map(|c| f(c).powi(2)).sum::<f64>() / n as f64).sqrt()
        };
        last[0] = format!("rms of {n}");
        last[4] = format!("{:.3}", rms(&|c| c.difference_mgal));
        last[6] = format!("{:.2}", rms(&|c| c.difference_mgal / c.sigma_mgal));
    }
    t.rows.push(last);
    t
}

fn summary(r: &GravityReport) -> String {
    let c = &r.calibration;
    format!(
        "The survey reduced to the {} (docs/formats.md 10; per session, {}): the \
         calibration of {} (model {}, {}; sha256 {}) applied, the specific force down formed \
         as follows: {}. Zero-phase {} with a cut-off period of {} s: a resolution (half \
         wavelength) of {:.0} m at the median speed of {:.1} m/s. Held to {} normal \
         gravity; {}. Epochs within one filter period of a stretch's ends are flagged edge \
         and given no filtered value (NaN): there it would lean on how the series is \
         extended past the end.",
        quantity(r),
        r.sessions
            .iter()
            .map(|s| format!("{}: {}", s.id, s.quantities.describe()))
            .collect::<Vec<_>>()
            .join("; "),
        c.dataset,
        c.model,
        c.session,
        &c.sha256[..c.sha256.len().min(12)],
        r.specific_force,
        r.filter.kind,
        r.filter.filter_s,
        r.filter.resolution_m,
        r.filter.median_speed_m_s,
        r.normal_gravity.name(),
        if r.earth_tide {
            "the body tide removed at every epoch"
        } else {
            "the body tide not removed (earth_tide = false)"
        }
    )
}

fn counts(m: &std::collections::BTreeMap<String, u64>) -> String {
    if m.is_empty() {
        return "none".to_owned();
    }
    m.iter()
        .map(|(k, n)| format!("{n} {k}"))
        .collect::<Vec<_>>()
        .join(", ")
}

fn reduced(r: &GravityReport) -> Table {
    let mut t =
        Table::headed("session | epochs read | used | dropped | flagged | stretches | gaps");
    for s in &r.sessions {
        t.rows.push(vec![
            s.id.clone(),
            s.epochs_read.to_string(),
            s.epochs_used.to_string(),
            if s.attitude_dropped.is_empty() {
                counts(&s.dropped)
            } else {
                format!(
                    "{}; of the attitude's samples, by the time gate: {}",
                    counts(&s.dropped),
                    counts(&s.attitude_dropped)
                )
            },
            counts(&s.flagged),
            s.stretches.len().to_string(),
            s.gaps.to_string(),
        ]);
    }
    t
}

/// Each antenna whose position was estimated (`position_m = "estimate"`): the position
/// with its sds, the epochs it rests on and those screened out, and the scatter's sigma0;
/// None when no antenna's was.
fn estimated_positions(r: &GravityReport) -> Option<Table> {
    let mut t = Table::headed(
        "session | antenna | x (m) | y (m) | z (m) | sds x, y, z (mm) | epochs | screened | sigma0",
    );
    for s in &r.sessions {
        let Some(a) = &s.antennas else { continue };
        for (id, e) in &a.estimated {
            let mut row = vec![s.id.clone(), id.clone()];
            row.extend(e.position_m.map(|v| format!("{v:.5}")));
            let [sx, sy, sz] = e.sd_m.map(|v| v * 1e3);
            row.push(format!("{sx:.3}, {sy:.3}, {sz:.3}"));
            row.extend([
                e.epochs.to_string(),
                e.screened.to_string(),
                format!("{:.3}", e.sigma0),
            ]);
            t.rows.push(row);
        }
    }
    (!t.rows.is_empty()).then_some(t)
}

fn ties(r: &GravityReport) -> Table {
    let mut t =
        Table::headed("session | from | to | epochs | ties | offset (mGal) | drift (mGal/h)");
    for s in &r.sessions {
        for st in &s.stretches {
            let (n, offset, drift) = match &st.drift {
                Some(d) => (
                    d.ties.to_string(),
                    format!("{:.3} ± {:.3}", d.offset_mgal, d.sigma_offset_mgal),
                    d.sigma_rate_mgal_per_h.map_or_else(
                        || "none (one tie)".to_owned(),
                        |sr| format!("{:.3} ± {sr:.3}", d.rate_mgal_per_h),
                    ),
                ),
                None => (
                    "0".to_owned(),
                    "untied: the calibration's level".to_owned(),
                    "none".to_owned(),
                ),
            };
            t.rows.push(vec![
                s.id.clone(),
                st.first.clone(),
                st.last.clone(),
                st.epochs.to_string(),
                n,
                offset,
                drift,
            ]);
        }
    }
    let unused = r.ties.iter().filter(|x| x.used_in.is_none()).count();
    if unused > 0 {
        t.rows.push(vec![
            format!("{unused} tie(s) unused"),
            "no stretch holds their still window".to_owned(),
            String::new(),
            String::new(),
            String::new(),
            String::new(),
            String::new(),
        ]);
    }
    t
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

fn disturbance(ds: &Dataset, epochs: &[Epoch]) -> Table {
    let mut t = Table::headed(
        "session | min | max | median sigma | calibration | positions | noise | tie | attitude | cross-coupling",
    );
    for (index, s) in ds.sessions.iter().enumerate() {
        let e: Vec<&Epoch> = epochs
            .iter()
            .filter(|e| usize::from(e.session) == index)
            .collect();
        if e.is_empty() {
            continue;
        }
        let (lo, hi) = e
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
                (a.min(x.filtered), b.max(x.filtered))
            });
        let mut row = vec![
            s.session.id.clone(),
            format!("{lo:.3}"),
            format!("{hi:.3}"),
            format!("{:.3}", median(e.iter().map(|x| x.sigma).collect())),
        ];
        for k in 0..6 {
            row.push(format!(
                "{:.3}",
                median(e.iter().map(|x| x.parts[k]).collect())
            ));
        }
        t.rows.push(row);
    }
    t
}

/// North and east per session where the table holds them (sessions with attitude): the
/// range of the filtered values, the median sigma and its parts; None when no session has
/// them.
fn horizontal(ds: &Dataset, path: &Path) -> Result<Option<Table>, Error> {
    use arrow_array::Array;
    let names = gravity::HORIZONTAL;
    // Per session, per column, the values of the rows that have them.
    let mut per: std::collections::BTreeMap<u16, Vec<Vec<f64>>> = Default::default();
    ingest::contract::tables::float_batches(path, &names, gravity::FLAGS, 1 << 16, |b| {
        for i in 0..b.time_ns.len() {
            if b.values[0].is_null(i) || b.flags[i] & gravity::EDGE != 0 {
                continue;
            }
            let cols = per
                .entry(b.session[i])
                .or_insert_with(|| vec![Vec::new(); names.len()]);
            // A sigma the attitude's sds would give is null without them: NaN here.
            for (c, v) in cols.iter_mut().enumerate() {
                v.push(if b.values[c].is_null(i) {
                    f64::NAN
                } else {
                    b.values[c].value(i)
                });
            }
        }
        Ok(())
    })?;
    if per.is_empty() {
        return Ok(None);
    }
    let mut t = Table::headed(
        "session | component | min | max | median sigma | calibration | positions | noise | attitude",
    );
    for (index, cols) in per {
        let id = ds
            .sessions
            .get(usize::from(index))
            .map_or_else(|| index.to_string(), |s| s.session.id.clone());
        for (c, name) in ["north", "east"].into_iter().enumerate() {
            let filtered = &cols[7 * c + 1];
            let (lo, hi) = filtered
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
                    (a.min(*x), b.max(*x))
                });
            let mut row = vec![
                id.clone(),
                name.to_owned(),
                format!("{lo:.1}"),
                format!("{hi:.1}"),
            ];
            for k in 2..7 {
                let known: Vec<f64> = cols[7 * c + k]
                    .iter()
                    .copied()
                    .filter(|v| !v.is_nan())
                    .collect();
                row.push(if known.is_empty() {
                    "unknown: the attitude gives no sd".to_owned()
                } else {
                    format!("{:.1}", median(known))
                });
            }
            t.rows.push(row);
        }
    }
    Ok(Some(t))
}

fn read(path: &Path) -> Result<Vec<Epoch>, Error> {
    let names = [
        gravity::LATITUDE_DEG,
        gravity::LONGITUDE_DEG,
        gravity::DOWN_FILTERED_MGAL,
        gravity::SIGMA_DOWN_MGAL,
        gravity::SIGMA_CALIBRATION_MGAL,
        gravity::SIGMA_POSITIONS_MGAL,
        gravity::SIGMA_NOISE_MGAL,
        gravity::SIGMA_TIE_MGAL,
        gravity::SIGMA_ATTITUDE_MGAL,
        gravity::SIGMA_COUPLING_MGAL,
    ];
    let mut out = Vec::new();
    ingest::contract::tables::float_batches(path, &names, gravity::FLAGS, 1 << 16, |b| {
        for i in 0..b.time_ns.len() {
            let v = |k: usize| b.values[k].value(i);
            // Within a filter period of a stretch's ends no filtered value is given.
            if v(2).is_nan() {
                continue;
            }
            out.push(Epoch {
                session: b.session[i],
                time_ns: b.time_ns[i],
                lat: v(0),
                lon: v(1),
                filtered: v(2),
                sigma: v(3),
                parts: [v(4), v(5), v(6), v(7), v(8), v(9)],
            });
        }
        Ok(())
    })?;
    Ok(out)
}

/// The profile's points, every `step`-th epoch: (distance km, filtered, sigma), a new
/// stretch where the epochs' interval jumps.
fn profile(
    e: &[&Epoch],
    step: usize,
    xy: &impl Fn(&Epoch) -> (f64, f64),
) -> Vec<Vec<(f64, f64, f64)>> {
    let interval = median(
        e.windows(2)
            .map(|w| (w[1].time_ns - w[0].time_ns) as f64)
            .collect(),
    );
    let mut stretches: Vec<Vec<(f64, f64, f64)>> = vec![Vec::new()];
    let mut distance = 0.0;
    for (k, x) in e.iter().enumerate() {
        if k > 0 {
            let (a, b) = (xy(e[k - 1]), xy(x));
            distance += (b.0 - a.0).hypot(b.1 - a.1);
            if (x.time_ns - e[k - 1].time_ns) as f64 > 1.5 * interval {
                stretches.push(Vec::new());
            }
        }
        if k % step == 0
            && let Some(last) = stretches.last_mut()
        {
            last.push((distance, x.filtered, x.sigma));
        }
    }
    stretches
}

/// The map and the profile, per session: east/north and distance from the session's first
/// epoch (a local flat frame: a survey of tens of km), a new stretch of the profile where
/// the epochs' interval jumps.
fn plots(epochs: &[Epoch], quantity: &str) -> Result<Vec<(String, String)>, Error> {
    let mut out = Vec::new();
    let sessions: std::collections::BTreeSet<u16> = epochs.iter().map(|e| e.session).collect();
    for index in sessions {
        let e: Vec<&Epoch> = epochs.iter().filter(|x| x.session == index).collect();
        let step = e.len().div_ceil(MAX_POINTS).max(1);
        let (lat0, lon0) = (e[0].lat, e[0].lon);
        let k_lat = 111.2;
        let k_lon = 111.2 * lat0.to_radians().cos();
        // East from the first epoch the short way round (a track across the antimeridian).
        let xy = |x: &Epoch| {
            let d_lon = adjust::survey::gravity::navigation::longitude_step_deg(lon0, x.lon);
            (d_lon * k_lon, (x.lat - lat0) * k_lat)
        };
        let map: Vec<(f64, f64, f64)> = e
            .iter()
            .step_by(step)
            .map(|x| {
                let (east, north) = xy(x);
                (east, north, x.filtered)
            })
            .collect();
        let stretches = profile(&e, step, &xy);
        let plot_err = |name: &str| {
            let name = name.to_owned();
            move |message| Error::Plot { name, message }
        };
        let map_name = format!("gravity_map_{index}.svg");
        let title = format!("Filtered {quantity} along the track");
        let svg = plots::track_map(&plots::TrackMap {
            title: &title,
            points: &map,
            value_label: "mGal",
        })
        .map_err(plot_err(&map_name))?;
        out.push((map_name, svg));
        out.push(band_plot(
            format!("gravity_profile_{index}.svg"),
            (&format!("Filtered {quantity}"), quantity, "mGal"),
            ("distance along the track (km)", "filtered"),
            &stretches,
        )?);
    }
    Ok(out)
}

/// A profile with its 1-sigma band, as `file`: titled "`subject` with its 1-sigma band",
/// its y axis `what (unit)`, against `x_label`, its line `legend`.
fn band_plot(
    file: String,
    (subject, what, unit): (&str, &str, &str),
    (x_label, legend): (&str, &str),
    stretches: &[Vec<(f64, f64, f64)>],
) -> Result<(String, String), Error> {
    let (title, y_label) = (
        format!("{subject} with its 1-sigma band"),
        format!("{what} ({unit})"),
    );
    let svg = plots::profile(&plots::Profile {
        title: &title,
        x_label,
        y_label: &y_label,
        legend,
        stretches,
    })
    .map_err(|message| Error::Plot {
        name: file.clone(),
        message,
    })?;
    Ok((file, svg))
}
