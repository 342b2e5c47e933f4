//! The navigation equation's geometry in the local north-east-down frame: the ellipsoid's
//! radii of curvature and the Coriolis and transport-rate term (2 omega_ie + omega_en) x v,
//! whose down component is the Eotvos correction (docs/model.md 7). No I/O.

use super::normal::Ellipsoid;

/// The step in longitude from `from_deg` to `to_deg`, deg, in [-180, 180): the short way
/// round, so that a track across the antimeridian (179.99 to -179.99) or across 0 in a file
/// writing 0 to 360 steps 0.02 deg and not 359.98.
pub fn longitude_step_deg(from_deg: f64, to_deg: f64) -> f64 {
    let d = to_deg - from_deg;
    d - 360.0 * ((d + 180.0) / 360.0).floor()
}

/// The step north and east from `from` to `to` (latitude, longitude, deg), m, on a sphere of
/// 6371 km at latitude `at_deg`: ample over the few seconds between neighbouring epochs
/// (a speed, a course, an outlier's distance from its prediction).
pub fn step_ne_m(from: [f64; 2], to: [f64; 2], at_deg: f64) -> [f64; 2] {
    let r = 6.371e6;
    [
        (to[0] - from[0]).to_radians() * r,
        longitude_step_deg(from[1], to[1]).to_radians() * r * at_deg.to_radians().cos(),
    ]
}

/// `lon_deg` in the range `like_deg` is written in: [0, 360) when it is 180 or more (a file
/// writing 0 to 360), [-180, 180) otherwise; so that a longitude interpolated across the
/// antimeridian (or across 0) reads as the file's own do.
pub fn longitude_wrapped_like(lon_deg: f64, like_deg: f64) -> f64 {
    if like_deg >= 180.0 {
        lon_deg.rem_euclid(360.0)
    } else {
        (lon_deg + 180.0).rem_euclid(360.0) - 180.0
    }
}

/// Meridian and prime-vertical radii of curvature (R_M, R_N) at geodetic latitude, m.
pub fn radii(e: &Ellipsoid, latitude_deg: f64) -> (f64, f64) {
    let s = latitude_deg.to_radians().sin();
    let w2 = 1.0 - e.e2() * s * s;
    let r_n = e.a / w2.sqrt();
    (r_n * (1.0 - e.e2()) / w2, r_n)
}

/// The down component of (2 omega_ie + omega_en) x v^n, m/s^2, for a velocity north and
/// east (m/s) at latitude and ellipsoidal height: 2 omega cos(phi) v_E plus
/// v_E^2 / (R_N + h) plus v_N^2 / (R_M + h). Gravity down is the measured down
/// acceleration plus this: moving east the instrument feels less gravity, moving west more.
pub fn eotvos_down(e: &Ellipsoid, latitude_deg: f64, height_m: f64, v_n: f64, v_e: f64) -> f64 {
    let (r_m, r_n) = radii(e, latitude_deg);
    2.0 * e.omega * latitude_deg.to_radians().cos() * v_e
        + v_e * v_e / (r_n + height_m)
        + v_n * v_n / (r_m + height_m)
}

/// The full Coriolis and transport-rate vector (north, east, down), m/s^2, for a velocity
/// (v_N, v_E, v_D): (2 omega_ie^n + omega_en^n) x v^n.
pub fn coriolis_transport(
    e: &Ellipsoid,
    latitude_deg: f64,
    height_m: f64,
    v: [f64; 3],
) -> [f64; 3] {
    let (r_m, r_n) = radii(e, latitude_deg);
    let (s, c) = latitude_deg.to_radians().sin_cos();
    let [v_n, v_e, v_d] = v;
    let w = [
        2.0 * e.omega * c + v_e / (r_n + height_m),
        -v_n / (r_m + height_m),
        -2.0 * e.omega * s - v_e * s / c / (r_n + height_m),
    ];
    [
        w[1] * v_d - w[2] * v_e,
        w[2] * v_n - w[0] * v_d,
        w[0] * v_e - w[1] * v_n,
    ]
}

#[cfg(test)]
mod tests {
    use super::super::normal::GRS80;
    use super::*;

    /// Across the antimeridian in a -180..180 file, and across 0 in a 0..360 one.
    #[test]
    fn a_longitude_is_wrapped_into_its_files_range() {
        assert!((longitude_wrapped_like(180.000_001, 179.99) + 179.999_999).abs() < 1e-9);
        assert!((longitude_wrapped_like(-0.000_001, 359.99) - 359.999_999).abs() < 1e-9);
        assert!((longitude_wrapped_like(5.01, 5.0) - 5.01).abs() < 1e-12);
        assert!((longitude_wrapped_like(200.0, 200.0) - 200.0).abs() < 1e-12);
    }

    /// The down component of the full vector is the Eotvos term, and at rest both vanish.
    #[test]
    fn the_down_component_is_the_eotvos_term() {
        for (lat, h, v) in [
            (45.0, 0.0, [3.0, 4.0, 0.0]),
            (-20.0, 3000.0, [-60.0, 10.0, 0.5]),
        ] {
            let full = coriolis_transport(&GRS80, lat, h, v);
            let down = eotvos_down(&GRS80, lat, h, v[0], v[1]);
            assert!((full[2] - down).abs() < 1e-15, "{full:?} {down}");
        }
        assert!(eotvos_down(&GRS80, 30.0, 0.0, 0.0, 0.0).abs() < 1e-300);
        // A ship going east at 5 m/s at 45 degrees: about 52 mGal.
        let e = eotvos_down(&GRS80, 45.0, 0.0, 0.0, 5.0) * 1e5;
        assert!((e - 51.96).abs() < 0.1, "{e}");
    }
}
