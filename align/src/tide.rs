//! The body tide of the solid Earth at the benchmark (docs/model.md section 6.3): the change of
//! gravity caused by the Moon and the Sun, by Longman's formulas (Longman 1959, "Formulas
//! for computing the tidal accelerations due to the Moon and the Sun", J. Geophys. Res.
//! 64(12), 2351-2355), with the mean elements of Schureman (1958), and the gravimetric
//! factor of an elastic Earth, `1 + h2 - 3/2 k2` = 1.16. No I/O.
//!
//! The result is the tide's effect on gravity (positive when gravity is larger than
//! tide-free), so that the gravity at an instant is `g_tide_free + body_tide_mgal(...)`.
//! It includes the permanent part of the tide, as a tide-free gravity value asks.
//! `tests/tide_reference.py` checks it against ETERNA (PyGTide) and against an independent
//! Longman implementation; docs/choices.md gives the figures.

/// Where the benchmark is.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Site {
    /// Geodetic latitude, deg, north positive.
    pub latitude_deg: f64,
    /// Longitude, deg, east positive.
    pub longitude_deg: f64,
    /// Height, m.
    pub height_m: f64,
}

/// Newton's constant, cgs (Longman's value).
const MU: f64 = 6.673e-8;
/// Mass of the Moon, g.
const MOON_G: f64 = 7.3537e25;
/// Mass of the Sun, g.
const SUN_G: f64 = 1.993e33;
/// Eccentricity of the Moon's orbit.
const E_MOON: f64 = 0.05490;
/// Ratio of the mean motion of the Sun to that of the Moon.
const M_RATIO: f64 = 0.074804;
/// Mean distance Earth-Moon, cm.
const C_MOON_CM: f64 = 3.84402e10;
/// Mean distance Earth-Sun, cm.
const C_SUN_CM: f64 = 1.495e13;
/// Equatorial radius, cm.
const A_CM: f64 = 6.378270e8;
/// Inclination of the Moon's orbit to the ecliptic, rad.
const I_MOON: f64 = 0.08979719;
/// Obliquity of the ecliptic, deg.
const OBLIQUITY_DEG: f64 = 23.452;
/// Love numbers of an elastic Earth.
const H2: f64 = 0.612;
const K2: f64 = 0.303;
/// The gravimetric factor `1 + h2 - 3/2 k2` (1.1575).
pub const GRAVIMETRIC_FACTOR: f64 = 1.0 + H2 - 1.5 * K2;

/// Seconds from 1899-12-31 12:00 UTC (Longman's epoch) to the GPS epoch 1980-01-06
/// 00:00 UTC: 29 224 days and 12 hours (JD 2444244.5 less JD 2415020.0).
const GPS_EPOCH_FROM_LONGMAN_S: f64 = 29_224.5 * 86_400.0;

fn poly(c: [f64; 4], t: f64) -> f64 {
    c[0] + t * (c[1] + t * (c[2] + t * c[3]))
}

/// Mean elements (Schureman), rad: the Moon's longitude s, its perigee p, the Sun's
/// longitude h, the Moon's node n, the Sun's perigee p1; and the Earth orbit's eccentricity
/// e1.
struct MeanElements {
    s: f64,
    p: f64,
    h: f64,
    n: f64,
    p1: f64,
    e1: f64,
}

impl MeanElements {
    /// The elements `t` Julian centuries after Longman's epoch.
    fn at(t: f64) -> MeanElements {
        let s = poly(
            [
                4.72000889397,
                8399.70927456,
                3.45575191895e-05,
                3.49065850399e-08,
            ],
            t,
        );
        let p = poly(
            [
                5.83515162814,
                71.0180412089,
                1.80108282532e-04,
                1.74532925199e-07,
            ],
            t,
        );
        let h = poly([4.88162798259, 628.331950894, 5.23598775598e-06, 0.0], t);
        let n = poly(
            [
                4.52360161181,
                -33.757146295,
                3.6264063347e-05,
                3.39369576777e-08,
            ],
            t,
        );
        let p1 = poly(
            [
                4.90822941839,
                0.0300025492114,
                7.85398163397e-06,
                5.3329504922e-08,
            ],
            t,
        );
        let e1 = 0.01675104 - 4.180e-5 * t - 1.26e-7 * t * t;
        MeanElements { s, p, h, n, p1, e1 }
    }
}

/// The body tide's effect on gravity at `site`, mGal, at `utc_s` seconds of UTC since the
/// GPS epoch (1980-01-06 00:00 UTC; that is, GPS time less the leap seconds since then).
pub fn body_tide_mgal(site: Site, utc_s: f64) -> f64 {
    let since_epoch_s = utc_s + GPS_EPOCH_FROM_LONGMAN_S;
    let t = since_epoch_s / (36_525.0 * 86_400.0); // Julian centuries
    let hour_of_day = (since_epoch_s / 3600.0 + 12.0).rem_euclid(24.0);
    let lat = site.latitude_deg.to_radians();
    let (sin_lat, cos_lat) = lat.sin_cos();
    let omega = OBLIQUITY_DEG.to_radians();

    let MeanElements { s, p, h, n, p1, e1 } = MeanElements::at(t);

    // The Moon's orbit against the equator.
    let incl = (omega.cos() * I_MOON.cos() - omega.sin() * I_MOON.sin() * n.cos()).acos();
    let nu = (I_MOON.sin() * n.sin() / incl.sin()).asin();
    // Hour angle of the mean Sun at the site (longitude east positive).
    let hour_angle = (15.0 * (hour_of_day - 12.0) + site.longitude_deg).to_radians();
    let chi = hour_angle + h - nu;
    let cos_alpha = n.cos() * nu.cos() + n.sin() * nu.sin() * omega.cos();
    let sin_alpha = omega.sin() * n.sin() / incl.sin();
    let alpha = 2.0 * (sin_alpha / (1.0 + cos_alpha)).atan();
    let sigma = s - (n - alpha);
    // The Moon's longitude in its orbit, with the main periodic terms.
    let l = sigma
        + 2.0 * E_MOON * (s - p).sin()
        + 1.25 * E_MOON * E_MOON * (2.0 * (s - p)).sin()
        + 3.75 * M_RATIO * E_MOON * (s - 2.0 * h + p).sin()
        + 1.375 * M_RATIO * M_RATIO * (2.0 * (s - h)).sin();
    let chi1 = hour_angle + h;
    let l1 = h + 2.0 * e1 * (h - p1).sin();

    // Zenith angles of the Moon and the Sun at the site.
    let half = |x: f64| ((0.5 * x).cos().powi(2), (0.5 * x).sin().powi(2));
    let (ci, si) = half(incl);
    let cos_moon =
        sin_lat * incl.sin() * l.sin() + cos_lat * (ci * (l - chi).cos() + si * (l + chi).cos());
    let (co, so) = half(omega);
    let cos_sun = sin_lat * omega.sin() * l1.sin()
        + cos_lat * (co * (l1 - chi1).cos() + so * (l1 + chi1).cos());

    // Distances: the site from the Earth's centre, the Moon and the Sun from it.
    let r = (1.0 / (1.0 + 0.006738 * sin_lat * sin_lat)).sqrt() * A_CM + site.height_m * 100.0;
    let ap = 1.0 / (C_MOON_CM * (1.0 - E_MOON * E_MOON));
    let ap1 = 1.0 / (C_SUN_CM * (1.0 - e1 * e1));
    let d = 1.0
        / (1.0 / C_MOON_CM
            + ap * E_MOON * (s - p).cos()
            + ap * E_MOON * E_MOON * (2.0 * (s - p)).cos()
            + 1.875 * ap * M_RATIO * E_MOON * (s - 2.0 * h + p).cos()
            + ap * M_RATIO * M_RATIO * (2.0 * (s - h)).cos());
    let big_d = 1.0 / (1.0 / C_SUN_CM + ap1 * e1 * (h - p1).cos());

    // Upward tidal accelerations (Longman's eq. 1 and its solar counterpart), cm/s^2.
    let moon = MU * MOON_G * r / d.powi(3) * (3.0 * cos_moon * cos_moon - 1.0)
        + 1.5 * MU * MOON_G * r * r / d.powi(4) * (5.0 * cos_moon.powi(3) - 3.0 * cos_moon);
    let sun = MU * SUN_G * r / big_d.powi(3) * (3.0 * cos_sun * cos_sun - 1.0);
    // An upward acceleration lowers gravity; cm/s^2 = 1000 mGal.
    -(moon + sun) * 1e3 * GRAVIMETRIC_FACTOR
}

/// UTC seconds since the GPS epoch of GPS time `gps_ns` (leap seconds from hifitime's table).
pub fn utc_seconds_of_gps(gps_ns: i64) -> f64 {
    let gpst = hifitime::Epoch::from_gpst_nanoseconds(gps_ns.max(0) as u64);
    let leap = gpst.leap_seconds(true).unwrap_or(0.0) - 19.0; // TAI-UTC less TAI-GPST
    gps_ns as f64 * 1e-9 - leap
}

#[cfg(test)]
mod tests {
    use super::*;

    const ESGT: Site = Site {
        latitude_deg: 48.0166,
        longitude_deg: 0.1576,
        height_m: 60.0,
    };

    /// Over a month the tide stays within its known size and swings by up to about 0.25 mGal
    /// a day, with the semidiurnal period dominant.
    #[test]
    fn size_and_rhythm() {
        let start = utc_seconds_of_gps(1310 * 604_800 * 1_000_000_000);
        let values: Vec<f64> = (0..30 * 24 * 6)
            .map(|i| body_tide_mgal(ESGT, start + f64::from(i) * 600.0))
            .collect();
        let (lo, hi) = values
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            });
        assert!(lo > -0.5 && hi < 0.5, "{lo} {hi}");
        assert!(hi - lo > 0.15 && hi - lo < 0.35, "peak to peak {}", hi - lo);
        assert!((GRAVIMETRIC_FACTOR - 1.1575).abs() < 1e-12);
    }

    #[test]
    fn leap_seconds_of_2005() {
        let gps_ns = 1310 * 604_800 * 1_000_000_000_i64;
        assert!((gps_ns as f64 * 1e-9 - utc_seconds_of_gps(gps_ns) - 13.0).abs() < 1e-9);
    }

    #[test]
    fn epoch_offset() {
        // 1899-12-31 12:00 is JD 2415020.0; 1980-01-06 00:00 is JD 2444244.5.
        assert!((GPS_EPOCH_FROM_LONGMAN_S / 86_400.0 - (2_444_244.5 - 2_415_020.0)).abs() < 1e-9);
    }
}
