//! The down component of the navigation equation on a simulated boat survey (docs/model.md
//! 7): 10 Hz positions of a boat that waits 5 minutes at the quay, steams east at 5 m/s
//! through 0.5 m waves for 100 minutes over a known gravity disturbance, and waits again;
//! the specific force it would feel. The reduction recovers the filtered disturbance
//! (signs, Eotvos, normal gravity, differentiator), a calibration bias is removed by the
//! two ties, and position noise scatters the result as the reported sigma says.

use adjust::survey::gravity::filter;
use adjust::survey::gravity::navigation::{eotvos_down, radii};
use adjust::survey::gravity::normal::GRS80;
use adjust::survey::gravity::reduce::{Stretch, Tie, reduce};

const DT: f64 = 0.1;
const QUAY_S: f64 = 300.0;
const STEAM_S: f64 = 6000.0;
const SPEED: f64 = 5.0;
const FILTER_S: f64 = 120.0;

/// The true disturbance at `x` m along the track, mGal.
fn disturbance(x: f64) -> f64 {
    8.0 * (2.0 * std::f64::consts::PI * x / 6000.0).sin()
        + 3.0 * (2.0 * std::f64::consts::PI * x / 15000.0).cos()
}

/// Speed at time t: 0 at the quay, a cosine ramp of 120 s to SPEED, and back.
fn speed(t: f64) -> f64 {
    let ramp = |u: f64| 0.5 - 0.5 * (std::f64::consts::PI * u.clamp(0.0, 1.0)).cos();
    let s = t - QUAY_S;
    SPEED * ramp(s / 120.0) * ramp((STEAM_S - s) / 120.0)
}

/// The survey: (stretch, true disturbance per epoch), with `bias` mGal added to the
/// specific force and `sd_up` m of white noise on the heights (seeded).
fn survey(bias: f64, sd_up: f64) -> (Stretch, Vec<f64>) {
    let n = ((2.0 * QUAY_S + STEAM_S) / DT) as usize;
    let mut s = Stretch::default();
    let mut truth = Vec::with_capacity(n);
    let (lat, mut lon, mut x) = (43.0_f64, 5.0_f64, 0.0_f64);
    let mut state = 99u64;
    let mut gauss = || {
        // Box-Muller on a small LCG: enough for a test.
        let mut u = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1442695040888963407);
            ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        let (a, b) = (u(), u());
        (-2.0 * a.ln()).sqrt() * (2.0 * std::f64::consts::PI * b).cos()
    };
    let (_, r_n) = radii(&GRS80, lat);
    for k in 0..n {
        let t = k as f64 * DT;
        let v = speed(t);
        let moving = v > 0.0;
        let w = 2.0 * std::f64::consts::PI / 8.0;
        let (h, hdd) = if moving {
            (
                2.0 + 0.5 * (v / SPEED) * (w * t).sin(),
                -0.5 * (v / SPEED) * w * w * (w * t).sin(),
            )
        } else {
            (2.0, 0.0)
        };
        let g_true = GRS80.normal_gravity_mgal(lat, h) + disturbance(x);
        let e = eotvos_down(&GRS80, lat, h, 0.0, v) * 1e5;
        // g_D = a_D - f_D + E, a_D = -h''.
        let f_down = -hdd * 1e5 + e - g_true + bias;
        s.time_gps_ns
            .push(1_400_000_000_000_000_000 + (t * 1e9).round() as i64);
        s.latitude_deg.push(lat);
        s.longitude_deg.push(lon);
        s.height_m.push(h + sd_up * gauss());
        s.sd_up_m.push(sd_up);
        s.f_down_mgal.push(f_down);
        s.sigma_f_mgal.push(0.5);
        s.noise_f_mgal.push(0.0);
        truth.push(disturbance(x));
        // Advance by the speed at the middle of the step.
        let vm = speed(t + DT / 2.0);
        x += vm * DT;
        lon += (vm * DT / (r_n * lat.to_radians().cos())).to_degrees();
    }
    (s, truth)
}

fn ties(s: &Stretch) -> Vec<Tie> {
    let t0 = s.time_gps_ns[0];
    let last = *s.time_gps_ns.last().expect("epochs");
    let x_end = (0..s.time_gps_ns.len())
        .map(|k| speed(k as f64 * DT) * DT)
        .sum::<f64>();
    let g = |x: f64| GRS80.normal_gravity_mgal(43.0, 2.0) + disturbance(x);
    vec![
        Tie {
            time_gps_ns: t0 + 150_000_000_000,
            duration_s: 240.0,
            g_mgal: g(0.0),
        },
        Tie {
            time_gps_ns: last - 150_000_000_000,
            duration_s: 240.0,
            g_mgal: g(x_end),
        },
    ]
}

/// The truth through the same filter, for a like-for-like comparison.
fn filtered_truth(truth: &[f64]) -> Vec<f64> {
    let sections = filter::butterworth(filter::ORDER, 1.0 / FILTER_S, 1.0 / DT).expect("filter");
    filter::filtfilt(&sections, truth).expect("filtered")
}

/// Epochs away from the ends and the ramps by three filter periods.
fn inner(n: usize) -> std::ops::Range<usize> {
    let m = ((QUAY_S + 3.0 * FILTER_S) / DT) as usize;
    m..n - m
}

#[test]
fn a_noiseless_survey_is_recovered() {
    let (s, truth) = survey(0.0, 0.0);
    let r = reduce(&s, FILTER_S, &[]).expect("reduced");
    let want = filtered_truth(&truth);
    let worst = inner(truth.len())
        .map(|k| (r.filtered_mgal[k] - want[k]).abs())
        .fold(0.0, f64::max);
    eprintln!(
        "noiseless: worst |filtered - filtered truth| {worst:.4} mGal; Eotvos {:.2} mGal at speed",
        r.eotvos_mgal[truth.len() / 2]
    );
    assert!(worst < 0.05, "{worst} mGal");
}

#[test]
fn a_bias_is_removed_by_the_ties() {
    let (s, truth) = survey(3.0, 0.0);
    let r = reduce(&s, FILTER_S, &ties(&s)).expect("reduced");
    let d = r.drift.expect("a drift");
    eprintln!(
        "bias 3 mGal: offset {:.4} +/- {:.4}, rate {:.4} mGal/h",
        d.offset_mgal, d.sigma_offset_mgal, d.rate_mgal_per_h
    );
    // 3 mGal more specific force down reads as 3 mGal less gravity: the misfit is -3.
    assert!(
        (d.offset_mgal + 3.0).abs() < 0.05 && d.rate_mgal_per_h.abs() < 0.05,
        "{d:?}"
    );
    let want = filtered_truth(&truth);
    let worst = inner(truth.len())
        .map(|k| (r.filtered_mgal[k] - want[k]).abs())
        .fold(0.0, f64::max);
    assert!(worst < 0.1, "{worst} mGal");
}

#[test]
fn position_noise_scatters_as_its_sigma_says() {
    let sd = 0.02;
    let (noisy, truth) = survey(0.0, sd);
    let r = reduce(&noisy, FILTER_S, &[]).expect("reduced");
    let want = filtered_truth(&truth);
    let range = inner(truth.len());
    let errs: Vec<f64> = range
        .clone()
        .map(|k| r.filtered_mgal[k] - want[k])
        .collect();
    let rms = (errs.iter().map(|e| e * e).sum::<f64>() / errs.len() as f64).sqrt();
    let sigma = r.sigma_positions_mgal[range.start];
    eprintln!(
        "2 cm heights at 10 Hz, {FILTER_S} s filter: rms error {rms:.4} mGal, reported sigma {sigma:.4} mGal"
    );
    assert!(
        rms / sigma > 0.8 && rms / sigma < 1.2,
        "rms {rms}, sigma {sigma}"
    );
}
