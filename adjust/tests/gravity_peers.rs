//! The gravity stage's pieces side by side with their peers (docs/model.md 7): GRS80 normal
//! gravity against boule (to 1 microGal, from the ellipsoid to 10 km), the zero-phase
//! filter against scipy.signal's `butter` + `sosfiltfilt` (to 1e-9 of the signal), and the
//! Eotvos term against shipgrav's `eotvos_full` (Harlan 1968) on a steady track and on
//! shipgrav's own test data, and that test data (a DGS meter's laptop file) through the
//! gravity stage as it is, against shipgrav's free-air anomaly. Run from
//! target/peers-venv (`bash .ci/peers-venv.sh`).

use adjust::survey::gravity::{filter, navigation, normal::GRS80};
use std::path::Path;
use std::process::Command;

#[path = "../../align/tests/peers/mod.rs"]
mod peers;

/// The reference script's rows, each split on commas into numbers.
fn reference(py: &Path, args: &[&str]) -> Vec<Vec<f64>> {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/gravity_reference.py");
    let o = Command::new(py)
        .arg(script)
        .args(args)
        .output()
        .expect("python runs");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8_lossy(&o.stdout)
        .lines()
        .map(|l| {
            l.split(',')
                .map(|x| x.trim().parse().expect("a number"))
                .collect()
        })
        .collect()
}

#[test]
fn normal_gravity_agrees_with_boule() {
    let Some(py) = peers::peers_python() else {
        return;
    };
    let rows = reference(&py, &["normal"]);
    assert!(rows.len() > 100, "{} points", rows.len());
    let worst = rows
        .iter()
        .map(|r| (GRS80.normal_gravity_mgal(r[0], r[1]) - r[2]).abs())
        .fold(0.0, f64::max);
    eprintln!(
        "normal gravity: worst |gravcal - boule| {:.3e} mGal over {} points",
        worst,
        rows.len()
    );
    assert!(worst < 1e-3, "{worst} mGal");
}

/// A deterministic test signal: a drift, three sines and a pseudo-random wobble.
fn signal(n: usize, fs: f64) -> Vec<f64> {
    let mut state = 12_345u64;
    (0..n)
        .map(|i| {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1);
            let noise = (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
            let t = i as f64 / fs;
            20.0 + 0.01 * t
                + 3.0 * (t / 300.0).sin()
                + (t / 7.0).sin()
                + 0.5 * (t * 2.1).cos()
                + noise
        })
        .collect()
}

#[test]
fn the_filter_agrees_with_scipy() {
    let Some(py) = peers::peers_python() else {
        return;
    };
    let dir = tempfile::tempdir().expect("tempdir");
    for (fs, period, n) in [(10.0, 100.0, 5000), (1.0, 60.0, 1200), (2.0, 30.0, 97)] {
        let x = signal(n, fs);
        let input = dir.path().join("x.txt");
        std::fs::write(
            &input,
            x.iter().map(|v| format!("{v:?}\n")).collect::<String>(),
        )
        .expect("write");
        let want: Vec<f64> = reference(
            &py,
            &[
                "filter",
                input.to_str().expect("utf-8"),
                &fs.to_string(),
                &period.to_string(),
            ],
        )
        .into_iter()
        .map(|r| r[0])
        .collect();
        let sections = filter::butterworth(filter::ORDER, 1.0 / period, fs).expect("filter");
        let got = filter::filtfilt(&sections, &x).expect("filtered");
        let scale = want.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        let worst = got
            .iter()
            .zip(&want)
            .map(|(a, b)| (a - b).abs() / scale)
            .fold(0.0, f64::max);
        eprintln!("filter {fs} Hz, {period} s, {n} samples: worst relative difference {worst:.2e}");
        assert_eq!(got.len(), want.len());
        assert!(worst < 1e-9, "{fs} Hz {period} s: {worst}");
    }
}

/// The named FIR kernels are scipy's: a Blackman or Hamming window's taps and sinc cut-off
/// as the stage designs them, given to `scipy.signal.firwin`, give the stage's taps to 1e-12
/// and, by `freqz`, a response of 0.5 at the cut-off; the Gaussian kernel is scipy's
/// `windows.gaussian` of its length and sd, its sum 1, with 0.5 at the cut-off to 1e-3.
#[test]
fn the_named_filters_are_scipys() {
    use ingest::contract::survey::FilterKind;
    let Some(py) = peers::peers_python() else {
        return;
    };
    for period in [30.0, 240.0] {
        for kind in [
            FilterKind::Blackman,
            FilterKind::Hamming,
            FilterKind::Gaussian,
        ] {
            let filter::Lowpass::Kernel(ours) =
                filter::Lowpass::design(kind, 1.0 / period, 1.0).expect("filter")
            else {
                panic!("{kind:?} is a kernel");
            };
            let p = period.to_string();
            let rows = if kind == FilterKind::Gaussian {
                let m = ours.len().to_string();
                let sd = filter::gaussian_sd(period).to_string();
                reference(&py, &["gaussian", &m, &sd, &p])
            } else {
                let (taps, cutoff) = filter::windowed_sinc_design(kind, period);
                assert_eq!(taps, ours.len());
                let (taps, cutoff) = (taps.to_string(), cutoff.to_string());
                reference(&py, &["firwin", kind.name(), &taps, &cutoff, &p])
            };
            let (taps, response) = rows.split_at(rows.len() - 1);
            let worst = ours
                .iter()
                .zip(taps)
                .map(|(a, b)| (a - b[0]).abs())
                .fold(0.0, f64::max);
            eprintln!(
                "{} over {period} s: {} taps, worst difference {worst:.1e}, scipy's response at \
                 the cut-off {:.6}",
                kind.name(),
                ours.len(),
                response[0][0]
            );
            assert_eq!(ours.len(), taps.len());
            assert!(worst < 1e-12, "{kind:?} {period}: {worst}");
            let tolerance = if kind == FilterKind::Gaussian {
                1e-3
            } else {
                1e-6
            };
            assert!(
                (response[0][0] - 0.5).abs() < tolerance,
                "{kind:?} {period}"
            );
        }
    }
}

/// Our Eotvos term on positions sampled at `fs`: velocities by central differences of
/// latitude and longitude (as shipgrav takes them), the ends left out.
fn ours(lon: &[f64], lat: &[f64], h: &[f64], fs: f64) -> Vec<f64> {
    (1..lat.len() - 1)
        .map(|i| {
            let (r_m, r_n) = navigation::radii(&GRS80, lat[i]);
            let dphi = (lat[i + 1] - lat[i - 1]).to_radians() * fs / 2.0;
            let dlam = (lon[i + 1] - lon[i - 1]).to_radians() * fs / 2.0;
            let v_n = (r_m + h[i]) * dphi;
            let v_e = (r_n + h[i]) * lat[i].to_radians().cos() * dlam;
            navigation::eotvos_down(&GRS80, lat[i], h[i], v_n, v_e) * 1e5
        })
        .collect()
}

#[test]
fn the_eotvos_term_agrees_with_shipgrav() {
    let Some(py) = peers::peers_python() else {
        return;
    };
    // A ship steaming at 5 m/s on a steady heading of 60 deg at 1 Hz for 20 minutes.
    let dir = tempfile::tempdir().expect("tempdir");
    let (mut lat, mut lon) = (vec![43.2], vec![5.3]);
    for _ in 1..1200 {
        let (r_m, r_n) = navigation::radii(&GRS80, *lat.last().expect("lat"));
        let (v_n, v_e) = (
            5.0 * 60f64.to_radians().cos(),
            5.0 * 60f64.to_radians().sin(),
        );
        let l = *lat.last().expect("lat");
        lat.push(l + (v_n / r_m).to_degrees());
        let m = *lon.last().expect("lon");
        lon.push(m + (v_e / (r_n * l.to_radians().cos())).to_degrees());
    }
    let h = vec![0.0; lat.len()];
    let input = dir.path().join("track.csv");
    let text: String = (0..lat.len())
        .map(|i| format!("{:?},{:?},{:?}\n", lon[i], lat[i], h[i]))
        .collect();
    std::fs::write(&input, text).expect("write");
    let want: Vec<f64> = reference(&py, &["eotvos", input.to_str().expect("utf-8"), "1"])
        .into_iter()
        .map(|r| r[0])
        .collect();
    let got = ours(&lon, &lat, &h, 1.0);
    let worst = got
        .iter()
        .zip(&want[1..want.len() - 1])
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    eprintln!(
        "eotvos, steady 5 m/s track: worst |gravcal - shipgrav| {worst:.4} mGal (term {:.2} mGal)",
        got[0]
    );
    assert!(worst < 0.01, "{worst} mGal");

    // shipgrav's own test data (a DGS marine meter's 1 Hz navigation, 1000 s): Harlan's
    // formula also holds the track's own accelerations (the second differences of latitude
    // and longitude), which the navigation equation carries in its kinematic acceleration;
    // the difference is reported, and bounded by what those terms can reach here.
    let rows = reference(&py, &["shipgrav-track"]);
    let (lon, lat): (Vec<f64>, Vec<f64>) = rows.iter().map(|r| (r[0], r[1])).unzip();
    let e: Vec<f64> = rows.iter().map(|r| r[2]).collect();
    let h = vec![0.0; lat.len()];
    let got = ours(&lon, &lat, &h, 1.0);
    let d: Vec<f64> = got
        .iter()
        .zip(&e[1..e.len() - 1])
        .map(|(a, b)| a - b)
        .collect();
    let rms = (d.iter().map(|x| x * x).sum::<f64>() / d.len() as f64).sqrt();
    let worst = d.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
    eprintln!(
        "eotvos on shipgrav's test data ({} epochs): first {:.5} vs shipgrav {:.5} mGal; rms difference {rms:.4}, worst {worst:.4} mGal",
        e.len(),
        got[0],
        e[1]
    );
    assert!((e[0] + 56.90367).abs() < 0.001, "shipgrav's own value");
    assert!(rms < 0.02 && worst < 0.1, "rms {rms}, worst {worst}");
}

/// shipgrav's DGS test record (fixtures/real/shipgrav-dgs) as it is, through the gravity
/// stage with the meter's stated offset (`--calibration vendor`, 969143 mGal as shipgrav's
/// tests take it), WGS84 normal gravity, `extra` lines of `[survey]`: the record's path,
/// the report and, per epoch, the value down (its free-air anomaly), normal gravity, tide
/// and cross-coupling.
fn dgs_reduced(
    extra: &str,
) -> (
    std::path::PathBuf,
    ingest::contract::gravity_ledger::GravityReport,
    Vec<[f64; 4]>,
) {
    let dir = tempfile::tempdir().expect("tempdir");
    dgs_reduced_into(dir.path(), extra)
}

/// [`dgs_reduced`] in `dir` (`dir/dgs` the dataset, `dir/out` its outputs).
fn dgs_reduced_into(
    dir: &Path,
    extra: &str,
) -> (
    std::path::PathBuf,
    ingest::contract::gravity_ledger::GravityReport,
    Vec<[f64; 4]>,
) {
    let ds = dir.join("dgs");
    std::fs::create_dir_all(ds.join("raw")).expect("raw");
    let record = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../fixtures/real/shipgrav-dgs/DGStest_laptop.dat");
    std::fs::copy(&record, ds.join("raw/DGStest_laptop.dat")).expect("copy");
    // shipgrav's tests take the meter's offset as 969143 mGal, as laptop_manifest states it.
    let survey =
        format!("filter_s = 240\nsample_noise_mgal = 1.0\nnormal_gravity = \"WGS84\"\n{extra}");
    let manifest = fixtures::meter::laptop_manifest(
        ("dgs-test", "2019-07-11"),
        "raw/DGStest_laptop.dat",
        &survey,
    );
    std::fs::write(ds.join("dataset.toml"), manifest).expect("manifest");
    let out = dir.join("out");
    let args = adjust::survey::gravity::stage::GravityArgs::new(
        &ds,
        Path::new(adjust::survey::apply::stream::VENDOR),
    );
    let report = args.run(&out).expect("the file reduces as it is");
    assert_eq!(report.sessions[0].epochs_used, 1001, "every epoch");
    let path = out
        .join("gravity")
        .join(ingest::contract::tables::gravity::FILE);
    let mut ours = Vec::new();
    ingest::contract::tables::float_batches(
        &path,
        &[
            "down_mgal",
            "normal_mgal",
            "tide_mgal",
            "cross_coupling_mgal",
        ],
        ingest::contract::tables::gravity::FLAGS,
        1 << 16,
        |b| {
            for i in 0..b.time_ns.len() {
                ours.push([0, 1, 2, 3].map(|c| b.values[c].value(i)));
            }
            Ok(())
        },
    )
    .expect("gravity.parquet");
    (record, report, ours)
}

/// shipgrav's DGS record through the stage with `filter = "blackman"` over 240 s, against
/// shipgrav's free-air anomaly of it filtered by scipy's `firwin` of the same taps and
/// cut-off (convolved, centred): the "the same normal gravity, tide and filter",
/// over the epochs the stage gives a filtered value (one filter period from either end).
#[test]
fn the_dgs_record_filtered_as_scipy_filters_shipgravs_anomaly() {
    use ingest::contract::survey::FilterKind;
    use ingest::contract::tables::gravity;
    let Some(py) = peers::peers_python() else {
        return;
    };
    let dir = tempfile::tempdir().expect("tempdir");
    let (record, _, _) = dgs_reduced_into(dir.path(), "filter = \"blackman\"\n");
    let path = dir.path().join("out/gravity").join(gravity::FILE);
    let mut ours = Vec::new();
    ingest::contract::tables::float_batches(
        &path,
        &["down_filtered_mgal"],
        gravity::FLAGS,
        1 << 16,
        |b| {
            ours.extend((0..b.time_ns.len()).map(|i| b.values[0].value(i)));
            Ok(())
        },
    )
    .expect("gravity.parquet");
    let (taps, cutoff) = filter::windowed_sinc_design(FilterKind::Blackman, 240.0);
    let kernel = reference(
        &py,
        &[
            "firwin",
            "blackman",
            &taps.to_string(),
            &cutoff.to_string(),
            "240",
        ],
    );
    let kernel: Vec<f64> = kernel[..taps].iter().map(|r| r[0]).collect();
    let faa: Vec<f64> = reference(&py, &["shipgrav-faa", record.to_str().expect("utf-8")])
        .iter()
        .map(|r| r[0])
        .collect();
    let half = taps / 2;
    let d: Vec<f64> = (half..faa.len() - half)
        .filter(|&i| ours[i].is_finite())
        .map(|i| {
            let theirs: f64 = (0..taps).map(|k| kernel[k] * faa[i + k - half]).sum();
            ours[i] - theirs
        })
        .collect();
    let rms = (d.iter().map(|x| x * x).sum::<f64>() / d.len() as f64).sqrt();
    eprintln!(
        "DGS record, 240 s Blackman ({taps} taps): filtered free-air anomaly against shipgrav's \
         filtered by scipy's kernel, rms {rms:.4} mGal over {} epochs",
        d.len()
    );
    assert!(d.len() > 400, "{} epochs compared", d.len());
    assert!(rms < 0.05, "rms {rms}");
}

/// shipgrav's six ships' navigation files (fixtures/real/shipgrav-nav), each with its
/// logger's prefix, through gravcal's NMEA reader as they are: the same fixes as shipgrav's
/// `read_nav` (its talker for each ship), latitude and longitude to 1e-9 deg, and the times
/// within a second (gravcal takes each sentence's own UTC time; shipgrav, for some ships,
/// the logger's clock); the heights above the ellipsoid where the GGA gives the geoid's
/// separation (altitude plus separation), above sea level where it does not.
#[test]
fn ships_nmea_files_read_as_shipgrav_reads_them() {
    use adjust::survey::gravity::trajectory::{nmea_scan, read_nmea};
    use ingest::contract::survey::Heights;
    let Some(py) = peers::peers_python() else {
        return;
    };
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/real/shipgrav-nav");
    // 2020-2023: GPS time is UTC plus 18 s.
    let unix_of_gps = |ns: i64| ns as f64 * 1e-9 + 315_964_800.0 - 18.0;
    for (ship, file, date, heights, first_h) in [
        (
            "Atlantis",
            "AT01_nav.gps",
            (2022, 7, 1),
            Heights::Ellipsoidal,
            25.169 - 30.062,
        ),
        (
            "Langseth",
            "MGL2003_nav.y2020d244",
            (2020, 8, 31),
            Heights::Ellipsoidal,
            1.62 - 7.75,
        ),
        (
            "NBP",
            "NBP_2301_nav.d013",
            (2023, 1, 13),
            Heights::Ellipsoidal,
            -1.36 - 56.73,
        ),
        (
            "Revelle",
            "RR2212_nav.txt",
            (2022, 11, 5),
            Heights::Ellipsoidal,
            -3.95 - 33.51,
        ),
        (
            "Ride",
            "SR2302_nav.raw",
            (2023, 1, 20),
            Heights::Ellipsoidal,
            -4.31 - 33.32,
        ),
        (
            "Thompson",
            "TN400_nav.Raw",
            (2022, 3, 13),
            Heights::SeaLevel,
            0.19,
        ),
    ] {
        let path = dir.join(file);
        let ours = read_nmea(&path, date, false).expect("read as it is");
        assert_eq!(nmea_scan(&path).expect("scan").heights, heights, "{file}");
        let theirs = reference(&py, &["shipgrav-nav", ship, path.to_str().expect("utf-8")]);
        assert_eq!(ours.time_gps_ns.len(), theirs.len(), "{file}");
        for (k, t) in theirs.iter().enumerate() {
            let dt = unix_of_gps(ours.time_gps_ns[k]) - t[0];
            assert!(dt.abs() < 1.0, "{file} fix {k}: {dt} s apart");
            assert!((ours.latitude_deg[k] - t[1]).abs() < 1e-9, "{file} {k}");
            assert!((ours.longitude_deg[k] - t[2]).abs() < 1e-9, "{file} {k}");
        }
        assert!(
            (ours.height_m[0] - first_h).abs() < 1e-9,
            "{file}: {}",
            ours.height_m[0]
        );
        eprintln!(
            "{file} ({ship}): {} fixes as shipgrav's, heights {heights:?}, the first {:.3} m",
            theirs.len(),
            ours.height_m[0]
        );
    }
}

/// shipgrav's ships' BGM-3 and DGS raw serial samples (fixtures/real/shipgrav-serial) read
/// as shipgrav's `read_bgm_raw` and `read_dgs_raw` read them: the same lines, the readings
/// (counts, AD units) equal, the monitors (scaled by 1e-5) to 1e-12 and the logger's times to
/// 1 us; R/V Sally Ride's file, whose ISO stamp shipgrav 1.0.11 does not convert ("raw
/// (serial) timestamps not found/converted"), is read with its stamps, the first checked by
/// hand. Every DGS line's checksum holds.
#[test]
fn meters_serial_files_read_as_shipgrav_reads_them() {
    use ingest::contract::manifest::TimeScale;
    use ingest::readers::meter_serial::{parse_bgm3, parse_dgs_raw};
    let Some(py) = peers::peers_python() else {
        return;
    };
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/real/shipgrav-serial");
    // 2020-2024: GPS time is UTC plus 18 s.
    let unix_of_gps = |ns: i64| ns as f64 * 1e-9 + 315_964_800.0 - 18.0;
    for (meter, ship, file) in [
        ("bgm3", "Atlantis", "AT01_bgm.BGM"),
        ("bgm3", "Langseth", "MGL2003_bgm.y2020d244"),
        ("bgm3", "Revelle", "RR2212_bgm.txt"),
        ("bgm3", "Thompson", "TN400_bgm.Raw"),
        ("dgs-raw", "Ride", "SR2312_dgs_raw.txt"),
        ("dgs-raw", "Thompson", "TN400_dgs_raw.Raw"),
        ("dgs-raw", "Sikuliaq", "SKQ_dgs_raw.20241018T2212Z"),
    ] {
        let path = dir.join(file);
        let bytes = std::fs::read(&path).expect("read");
        let ours: Vec<_> = bytes
            .split(|&c| c == b'\n')
            .filter(|l| !l.trim_ascii().is_empty() && !l.starts_with(b"#"))
            .map(|l| match meter {
                "bgm3" => parse_bgm3(l, TimeScale::Utc),
                _ => parse_dgs_raw(l, TimeScale::Utc),
            })
            .collect::<Result<_, _>>()
            .unwrap_or_else(|e| panic!("{file}: {e:?}"));
        let theirs = reference(
            &py,
            &[
                "shipgrav-serial",
                meter,
                ship,
                path.to_str().expect("utf-8"),
            ],
        );
        assert_eq!(ours.len(), theirs.len(), "{file}");
        for (k, (o, t)) in ours.iter().zip(&theirs).enumerate() {
            if t[0].is_nan() {
                assert_eq!(
                    file, "SR2312_dgs_raw.txt",
                    "{file} {k}: shipgrav found no time"
                );
            } else {
                let dt = unix_of_gps(o.gps_ns) - t[0];
                assert!(dt.abs() < 1e-6, "{file} line {k}: {dt} s apart");
            }
            assert_eq!(o.reading.to_bits(), t[1].to_bits(), "{file} line {k}");
            for (i, m) in o.monitors.unwrap_or([f64::NAN; 4]).iter().enumerate() {
                let close = (m - t[2 + i]).abs() < 1e-12 || (m.is_nan() && t[2 + i].is_nan());
                assert!(
                    close,
                    "{file} line {k} monitor {i}: {m} against {}",
                    t[2 + i]
                );
            }
        }
        eprintln!(
            "{file} ({ship}, {meter}): {} lines as shipgrav's, stamps {}",
            ours.len(),
            ours[0].form.name()
        );
    }
    let ride = std::fs::read(dir.join("SR2312_dgs_raw.txt")).expect("read");
    let first = parse_dgs_raw(
        ride.split(|&c| c == b'\n').next().expect("a line"),
        TimeScale::Utc,
    );
    let at = ingest::base::time::iso_gps_ns("2023-06-16T00:00:00.857719Z", TimeScale::Utc);
    assert_eq!(first.map(|l| l.gps_ns).ok(), at.ok());
}

/// A damaged sentence costs its line alone: its checksum refuses it, naming file, line and
/// field, and with `--skip-bad-lines` the other fixes are read; a fix that is none (GGA
/// quality 0) is a bad line as well, never a position.
#[test]
fn a_damaged_nmea_sentence_costs_its_line_alone() {
    use adjust::survey::gravity::trajectory::read_nmea;
    let src =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/real/shipgrav-nav/AT01_nav.gps");
    let text = std::fs::read_to_string(src).expect("read");
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("nav.gps");
    // The first GGA's latitude changed, its checksum kept.
    let gga = text.lines().nth(3).expect("the first GGA");
    let damaged = text.replacen(gga, &gga.replacen("4131.403226,N", "4131.403227,N", 1), 1);
    std::fs::write(&path, damaged).expect("write");
    let e = read_nmea(&path, (2022, 7, 1), false)
        .expect_err("damaged")
        .to_string();
    assert!(e.contains("nav.gps:4") && e.contains("checksum"), "{e}");
    let t = read_nmea(&path, (2022, 7, 1), true).expect("the others read");
    assert_eq!(
        (t.time_gps_ns.len(), t.bad_lines.len()),
        (1, 1),
        "{:?}",
        t.bad_lines
    );
    // A GGA without a fix (quality 0), its checksum made again.
    let line = gga;
    let body = &line[line.find('$').expect("$") + 1..line.find('*').expect("*")];
    let no_fix = body.replacen(",W,2,", ",W,0,", 1);
    let sum = no_fix.bytes().fold(0u8, |a, b| a ^ b);
    let fixed = text.replacen(line, &format!("${no_fix}*{sum:02X}"), 1);
    std::fs::write(&path, fixed).expect("write");
    let e = read_nmea(&path, (2022, 7, 1), false)
        .expect_err("no fix")
        .to_string();
    assert!(e.contains("quality") && e.contains("no fix"), "{e}");
}

/// The DGS record's navigation has no height: the sea surface, above sea level, so its value
/// down is the free-air anomaly, named so (docs/formats.md 10.3), and the disturbance is not
/// formed; with `[survey] geoid_height_m` the disturbance is the anomaly plus normal
/// gravity's change over the geoid's height (about 0.3086 mGal/m).
#[test]
fn the_dgs_record_gives_the_free_air_anomaly_and_with_a_geoid_height_the_disturbance() {
    use arrow_array::Array as _;
    use ingest::contract::tables::gravity;
    let named = |extra: &str| {
        let dir = tempfile::tempdir().expect("tempdir");
        let (_, report, _) = dgs_reduced_into(dir.path(), extra);
        let mut rows = Vec::new();
        let path = dir.path().join("out/gravity").join(gravity::FILE);
        let names = ["down_filtered_mgal", gravity::NAMED[0], gravity::NAMED[1]];
        ingest::contract::tables::float_batches(&path, &names, gravity::FLAGS, 1 << 16, |b| {
            for i in 0..b.time_ns.len() {
                let at = |c: usize| (!b.values[c].is_null(i)).then(|| b.values[c].value(i));
                rows.push((b.values[0].value(i), at(1), at(2)));
            }
            Ok(())
        })
        .expect("gravity.parquet");
        (report.sessions[0].quantities.clone(), rows)
    };
    let (q, rows) = named("");
    assert!(!q.disturbance && q.free_air_anomaly, "{q:?}");
    assert!(rows.iter().any(|r| r.0.is_finite()));
    for (down, disturbance, anomaly) in &rows {
        assert!(disturbance.is_none());
        assert!(anomaly.expect("formed").total_cmp(down).is_eq());
    }
    let (q, rows) = named("geoid_height_m = 55.0\n");
    assert!(q.disturbance && q.free_air_anomaly, "{q:?}");
    for (down, disturbance, anomaly) in rows.iter().filter(|r| r.0.is_finite()) {
        let shift = disturbance.expect("formed") - anomaly.expect("formed");
        assert!(anomaly.expect("formed").total_cmp(down).is_eq());
        assert!((shift - 0.3086 * 55.0).abs() < 0.05, "{shift}");
    }
}

/// shipgrav's DGS AT1M test file (fixtures/real/shipgrav-dgs), as it is, through the gravity
/// stage with the meter's stated offset (`--calibration vendor`, as shipgrav's tests take
/// it: 969143 mGal) and the file's own navigation (issue 48): its free-air anomaly, held to
/// WGS84 normal gravity as shipgrav's is, agrees with shipgrav's epoch by epoch (neither
/// with a tide; the Eotvos terms differ by the track's own accelerations, above) and its
/// 240 s means agree to a microGal.
/// A difference's rms over the epochs 5 from either end, and its worst 240 s mean there.
fn agreement(d: &[f64]) -> (f64, f64) {
    let interior = &d[5..d.len() - 5];
    let rms = (interior.iter().map(|x| x * x).sum::<f64>() / interior.len() as f64).sqrt();
    let worst_mean = interior
        .windows(240)
        .map(|w| (w.iter().sum::<f64>() / 240.0).abs())
        .fold(0.0_f64, f64::max);
    (rms, worst_mean)
}

#[test]
fn a_dgs_laptop_file_reduces_as_shipgrav_reduces_it() {
    let Some(py) = peers::peers_python() else {
        return;
    };
    let (record, _, ours) = dgs_reduced("");
    let want = reference(&py, &["shipgrav-faa", record.to_str().expect("utf-8")]);
    assert_eq!(ours.len(), want.len());
    assert!(
        ours.iter()
            .zip(&want)
            .all(|(o, w)| (o[1] - w[1]).abs() < 1e-3),
        "the same normal gravity, WGS84's"
    );
    // shipgrav's tide is the correction (added), ours the effect (removed).
    let tides = ours
        .iter()
        .zip(&want)
        .map(|(o, w)| (o[2] + w[2]).abs())
        .fold(0.0, f64::max);
    let d: Vec<f64> = ours.iter().zip(&want).map(|(o, w)| o[0] - w[0]).collect();
    let (rms, worst_mean) = agreement(&d);
    eprintln!(
        "DGS laptop file: free-air anomaly against shipgrav's, rms {rms:.4} mGal epoch by \
         epoch, worst 240 s mean {worst_mean:.4} mGal; the tides {:.4} mGal at the start, \
         apart by {tides:.4} mGal at most",
        ours[0][2]
    );
    assert!(tides < 0.005, "the tides apart by {tides} mGal");
    assert!(
        rms < 0.02 && worst_mean < 0.005,
        "rms {rms}, worst mean {worst_mean}"
    );
}

/// The cross-coupling fit against shipgrav's `calc_cross_coupling_coefficients` on the
/// series shipgrav gives it (its test record's anomaly and the meter's four monitors): the
/// same coefficients and ordinary sds to 1e-6 of each (the arithmetic is LaCoste's as
/// shipgrav does it), and the sds gravcal carries (the frequency-domain jackknife's)
/// printed beside the ordinary ones.
#[test]
fn the_cross_coupling_fit_agrees_with_shipgrav() {
    use adjust::survey::gravity::coupling;
    let Some(py) = peers::peers_python() else {
        return;
    };
    let record = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../fixtures/real/shipgrav-dgs/DGStest_laptop.dat");
    let rows = reference(&py, &["shipgrav-ccp", record.to_str().expect("utf-8")]);
    let (want, want_sd) = (&rows[0], &rows[1]);
    let anomaly: Vec<f64> = rows[2..].iter().map(|r| r[0]).collect();
    let monitors: Vec<[f64; 4]> = rows[2..].iter().map(|r| [r[1], r[2], r[3], r[4]]).collect();
    let f = coupling::fit(&coupling::segment_rows(&anomaly, &monitors))
        .expect("the record determines them");
    for i in 0..5 {
        let sd = f.covariance[i][i].sqrt();
        eprintln!(
            "{}: gravcal {:.6e} (OLS sd {:.3e}, jackknife sd {sd:.3e}); shipgrav {:.6e} (sd {:.3e})",
            ["const", "ve", "vcc", "al", "ax"][i],
            f.coefficients[i],
            f.ols_sigma[i],
            want[i],
            want_sd[i]
        );
        assert!(
            (f.coefficients[i] - want[i]).abs() <= 1e-6 * want[i].abs().max(1e-9),
            "{i}"
        );
        assert!(
            (f.ols_sigma[i] - want_sd[i]).abs() <= 1e-6 * want_sd[i],
            "{i}"
        );
    }
}

/// The same record with `cross_coupling = "fit"` (issue 48): the stage's coefficients, fitted
/// to its own anomaly, are within their (carried) sigmas of shipgrav's fit to shipgrav's
/// anomaly, and the corrected anomaly agrees with shipgrav's corrected one (its anomaly plus
/// its coefficients times the monitors) epoch by epoch and over every 240 s mean, the
/// correction itself being 2.5 mGal rms.
#[test]
fn the_dgs_record_is_corrected_for_cross_coupling_as_shipgrav_corrects_it() {
    let Some(py) = peers::peers_python() else {
        return;
    };
    let (record, report, ours) = dgs_reduced("cross_coupling = \"fit\"\n");
    let rows = reference(&py, &["shipgrav-ccp", record.to_str().expect("utf-8")]);
    let c = report.sessions[0].cross_coupling.as_ref().expect("fitted");
    for i in 0..4 {
        let z = (c.coefficients[i] - rows[0][i + 1]) / c.sigma[i];
        eprintln!(
            "{}: gravcal {:.4e} +/- {:.2e}, shipgrav {:.4e}: z {z:.3}",
            adjust::survey::gravity::coupling::MONITORS[i],
            c.coefficients[i],
            c.sigma[i],
            rows[0][i + 1]
        );
        assert!(z.abs() < 1.0, "{i}: z {z}");
    }
    let corrected: Vec<f64> = rows[2..]
        .iter()
        .map(|r| r[0] + (0..4).map(|i| rows[0][i + 1] * r[i + 1]).sum::<f64>())
        .collect();
    let d: Vec<f64> = ours.iter().zip(&corrected).map(|(o, w)| o[0] - w).collect();
    let (rms, worst_mean) = agreement(&d);
    let mean = ours.iter().map(|o| o[3]).sum::<f64>() / ours.len() as f64;
    let size = (ours.iter().map(|o| (o[3] - mean).powi(2)).sum::<f64>() / ours.len() as f64).sqrt();
    eprintln!(
        "corrected for cross-coupling ({size:.2} mGal rms): against shipgrav's, rms {rms:.4} \
         mGal epoch by epoch, worst 240 s mean {worst_mean:.4} mGal"
    );
    assert!(size > 1.0, "a correction of {size} mGal");
    assert!(
        rms < 0.05 && worst_mean < 0.01,
        "rms {rms}, worst mean {worst_mean}"
    );
    // shipgrav's coefficients given: applied as they are, exact.
    let given = format!(
        "cross_coupling = {{ ve = {:?}, vcc = {:?}, al = {:?}, ax = {:?} }}\n",
        rows[0][1], rows[0][2], rows[0][3], rows[0][4]
    );
    let (_, report, ours) = dgs_reduced(&given);
    let c = report.sessions[0].cross_coupling.as_ref().expect("given");
    assert!(
        c.how == "given" && c.sigma.iter().all(|s| *s == 0.0),
        "{c:?}"
    );
    let d: Vec<f64> = ours.iter().zip(&corrected).map(|(o, w)| o[0] - w).collect();
    let (rms, _) = agreement(&d);
    eprintln!("shipgrav's coefficients given: rms {rms:.4} mGal against shipgrav's");
    assert!(rms < 0.02, "rms {rms}");
}

/// gravity.parquet's `meter_status` column and flags, by row.
fn status_column(out: &Path) -> Vec<(Option<u32>, u8)> {
    use arrow_array::Array as _;
    use arrow_array::cast::AsArray as _;
    use arrow_array::types::{UInt8Type, UInt32Type};
    use ingest::contract::tables::gravity;
    let file = std::fs::File::open(out.join("gravity").join(gravity::FILE)).expect("parquet");
    let reader = parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder::try_new(file)
        .expect("reader")
        .build()
        .expect("reader");
    let mut rows = Vec::new();
    for batch in reader {
        let batch = batch.expect("batch");
        let words = batch
            .column_by_name(gravity::METER_STATUS_WORD)
            .expect("meter_status")
            .as_primitive::<UInt32Type>()
            .clone();
        let flags = batch
            .column_by_name(gravity::FLAGS)
            .expect("flags")
            .as_primitive::<UInt8Type>()
            .clone();
        for i in 0..batch.num_rows() {
            rows.push(((!words.is_null(i)).then(|| words.value(i)), flags.value(i)));
        }
    }
    rows
}

/// shipgrav's DGS record's status words (field 7, 20814 on every line) as the stage gives
/// them: per epoch in `meter_status`, per bit in gravity.json (the bits the test finds in
/// the file itself, at every epoch), and flagging an epoch `meter_status` exactly where a
/// declared bit is set: none with bit 0 declared, every epoch with bit 12; the record with
/// 50 lines' bit 0 set (a clamp, say) flags those 50 alone. A bit beyond 31, or bits
/// declared for a session that is no meter's file, is refused by key.
#[test]
fn the_dgs_record_s_status_words_are_counted_and_flag_as_declared() {
    use ingest::contract::tables::gravity::METER_STATUS;
    let record = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../fixtures/real/shipgrav-dgs/DGStest_laptop.dat"),
    )
    .expect("record");
    let words: Vec<u32> = record
        .lines()
        .map(|l| {
            l.split(',')
                .nth(6)
                .expect("field 7")
                .trim()
                .parse()
                .expect("word")
        })
        .collect();
    assert_eq!(words.len(), 1001);
    let set: std::collections::BTreeMap<u8, u64> = (0u8..32)
        .map(|b| (b, words.iter().filter(|w| *w >> b & 1 == 1).count() as u64))
        .filter(|(_, n)| *n > 0)
        .collect();
    for (flag_bits, flagged) in [("[0]", 0), ("[0, 12]", 1001)] {
        let dir = tempfile::tempdir().expect("tempdir");
        let (_, report, _) = dgs_reduced_into(
            dir.path(),
            &format!("meter_status_flag_bits = {flag_bits}\n"),
        );
        let status = report.sessions[0].meter_status.clone().expect("a meter's");
        eprintln!("{flag_bits}: {status:?}");
        assert_eq!(status.epochs, 1001);
        assert_eq!(status.bits_set, set);
        let rows = status_column(&dir.path().join("out"));
        assert_eq!(rows.len(), 1001);
        assert!(rows.iter().zip(&words).all(|(r, w)| r.0 == Some(*w)));
        let n = rows.iter().filter(|r| r.1 & METER_STATUS != 0).count();
        assert_eq!(n, flagged, "{flag_bits}");
        let named = report.sessions[0].flagged.get("meter_status").copied();
        assert_eq!(named.unwrap_or(0), flagged as u64);
    }
    // Bit 0 set on lines 301 to 350 of the record.
    let dir = tempfile::tempdir().expect("tempdir");
    let clamped: String = record
        .lines()
        .enumerate()
        .map(|(k, l)| {
            let mut f: Vec<String> = l.split(',').map(str::to_owned).collect();
            if (300..350).contains(&k) {
                f[6] = (words[k] | 1).to_string();
            }
            f.join(",") + "\n"
        })
        .collect();
    dgs_reduced_into(dir.path(), "meter_status_flag_bits = [0]\n");
    let ds = dir.path().join("dgs");
    std::fs::write(ds.join("raw/DGStest_laptop.dat"), clamped).expect("clamped");
    let out = dir.path().join("clamped");
    let args = adjust::survey::gravity::stage::GravityArgs::new(
        &ds,
        Path::new(adjust::survey::apply::stream::VENDOR),
    );
    let report = args.run(&out).expect("the clamped record reduces");
    let rows = status_column(&out);
    let flagged: Vec<usize> = (0..rows.len())
        .filter(|&k| rows[k].1 & METER_STATUS != 0)
        .collect();
    assert_eq!(flagged, (300..350).collect::<Vec<_>>());
    let status = report.sessions[0].meter_status.clone().expect("a meter's");
    assert_eq!(status.bits_set.get(&0), Some(&50));
    // A bit beyond a 32-bit word's, refused by key.
    let toml = std::fs::read_to_string(ds.join("dataset.toml")).expect("toml");
    let beyond = toml.replace(
        "meter_status_flag_bits = [0]",
        "meter_status_flag_bits = [0, 32]",
    );
    assert_ne!(beyond, toml);
    std::fs::write(ds.join("dataset.toml"), beyond).expect("toml");
    let e = args
        .run(&dir.path().join("beyond"))
        .expect_err("bit 32")
        .to_string();
    eprintln!("{e}");
    assert!(
        e.contains("survey.meter_status_flag_bits") && e.contains("bit 32"),
        "{e}"
    );
}
