//! Normal gravity of a level ellipsoid (GRS80, WGS84) at a point given by geodetic latitude
//! and ellipsoidal height: the magnitude of the normal gravity vector in closed form from the
//! ellipsoidal-harmonic coordinates (u, beta) of the point (Hofmann-Wellenhof and Moritz
//! 2006, section 2.7; Li and Goetze 2001), so no free-air series is needed at aircraft
//! heights. Valid on and above the ellipsoid. No I/O. It lives in the contract because more
//! than one stage holds values to it: the manifest's check of a benchmark's gravity, and the
//! gravity stage's `normal_mgal`.

/// The largest departure from normal gravity any place on the Earth has, mGal: free-air
/// disturbances and anomalies stay within a few hundred mGal, so a gravity farther from
/// normal gravity (a benchmark's, a tie's, a filtered disturbance) belongs to another place,
/// or the values it is held to do.
pub const MAX_DISTURBANCE_MGAL: f64 = 1000.0;

/// Which ellipsoid's normal gravity a survey is held to (`[survey] normal_gravity`,
/// docs/formats.md 11.1): GRS80 by default, WGS84 as marine users' software (shipgrav)
/// takes it; 0.14 mGal apart at mid-latitudes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
pub enum NormalGravity {
    /// [`GRS80`].
    #[default]
    #[serde(rename = "GRS80")]
    Grs80,
    /// [`WGS84`].
    #[serde(rename = "WGS84")]
    Wgs84,
}

impl NormalGravity {
    /// Its ellipsoid.
    pub fn ellipsoid(self) -> &'static Ellipsoid {
        match self {
            NormalGravity::Grs80 => &GRS80,
            NormalGravity::Wgs84 => &WGS84,
        }
    }

    /// The name as in the manifest.
    pub fn name(self) -> &'static str {
        match self {
            NormalGravity::Grs80 => "GRS80",
            NormalGravity::Wgs84 => "WGS84",
        }
    }
}

/// A level ellipsoid: its four defining constants.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ellipsoid {
    /// Semi-major axis a, m.
    pub a: f64,
    /// Flattening f.
    pub f: f64,
    /// Geocentric gravitational constant GM, m^3/s^2.
    pub gm: f64,
    /// Angular velocity omega, rad/s.
    pub omega: f64,
}

/// The Geodetic Reference System 1980 (Moritz 1988).
pub const GRS80: Ellipsoid = Ellipsoid {
    a: 6_378_137.0,
    f: 1.0 / 298.257_222_101,
    gm: 3.986_005e14,
    omega: 7.292_115e-5,
};

/// The World Geodetic System 1984 (NIMA TR8350.2, 2000): GRS80's a and omega, its own f and
/// GM.
pub const WGS84: Ellipsoid = Ellipsoid {
    a: 6_378_137.0,
    f: 1.0 / 298.257_223_563,
    gm: 3.986_004_418e14,
    omega: 7.292_115e-5,
};

impl Ellipsoid {
    /// Semi-minor axis b, m.
    pub fn b(&self) -> f64 {
        self.a * (1.0 - self.f)
    }

    /// First eccentricity squared.
    pub fn e2(&self) -> f64 {
        self.f * (2.0 - self.f)
    }

    /// Linear eccentricity E = sqrt(a^2 - b^2), m.
    pub fn linear_eccentricity(&self) -> f64 {
        (self.a * self.a - self.b() * self.b()).sqrt()
    }

    /// The point's ellipsoidal-harmonic coordinates: (sin^2 of its reduced latitude beta,
    /// u, the semi-minor axis of the confocal ellipsoid through it).
    fn harmonic(&self, latitude_deg: f64, height_m: f64) -> (f64, f64) {
        let (a, b, h) = (self.a, self.b(), height_m);
        let e2_lin = a * a - b * b;
        let (sin_phi, cos_phi) = latitude_deg.to_radians().sin_cos();
        // The foot point's reduced latitude, then the point's cylindrical coordinates.
        let beta0 = (b * sin_phi).atan2(a * cos_phi);
        let (sb, cb) = beta0.sin_cos();
        let z = b * sb + h * sin_phi;
        let r = a * cb + h * cos_phi;
        let (z2, r2) = (z * z, r * r);
        // cos^2 of the point's reduced latitude: a root of the confocal ellipsoid's equation.
        let big_r = (r2 + z2) / e2_lin;
        let big_d = (r2 - z2) / e2_lin;
        let cos2 = (0.5 + big_r / 2.0 - (0.25 + big_r * big_r / 4.0 - big_d / 2.0).sqrt()).abs();
        let u = (r2 + z2 - e2_lin * cos2).sqrt();
        (1.0 - cos2, u)
    }

    /// Normal gravity at geodetic latitude `latitude_deg` and ellipsoidal height `height_m`
    /// (on or above the ellipsoid), m/s^2.
    pub fn normal_gravity(&self, latitude_deg: f64, height_m: f64) -> f64 {
        self.field().normal_gravity(latitude_deg, height_m)
    }

    /// What normal gravity takes of the ellipsoid alone, computed once for many points.
    pub fn field(&self) -> NormalField<'_> {
        let (b, e) = (self.b(), self.linear_eccentricity());
        let e2 = e * e;
        NormalField {
            ellipsoid: self,
            e,
            e2,
            q0: 0.5 * ((1.0 + 3.0 * b * b / e2) * e.atan2(b) - 3.0 * b / e),
        }
    }

    /// Normal gravity in mGal.
    pub fn normal_gravity_mgal(&self, latitude_deg: f64, height_m: f64) -> f64 {
        self.normal_gravity(latitude_deg, height_m) * 1e5
    }
}

/// An ellipsoid's normal field: what [`Ellipsoid::normal_gravity`] takes of the ellipsoid
/// alone (its linear eccentricity and q0), for the points of a survey.
#[derive(Clone, Copy, Debug)]
pub struct NormalField<'a> {
    ellipsoid: &'a Ellipsoid,
    e: f64,
    e2: f64,
    q0: f64,
}

impl NormalField<'_> {
    /// Normal gravity at geodetic latitude `latitude_deg` and ellipsoidal height `height_m`
    /// (on or above the ellipsoid), m/s^2.
    pub fn normal_gravity(&self, latitude_deg: f64, height_m: f64) -> f64 {
        let NormalField {
            ellipsoid,
            e,
            e2,
            q0,
        } = *self;
        let (sin2_beta, u) = ellipsoid.harmonic(latitude_deg, height_m);
        let q_prime = 3.0 * (1.0 + u * u / e2) * (1.0 - u / e * e.atan2(u)) - 1.0;
        let w = ((u * u + e2 * sin2_beta) / (u * u + e2)).sqrt();
        let radial = ellipsoid.gm / (u * u + e2);
        let rotation = (0.5 * sin2_beta - 1.0 / 6.0)
            * (ellipsoid.a * ellipsoid.a * e * q_prime / q0 * ellipsoid.omega * ellipsoid.omega
                / (u * u + e2));
        let centrifugal = -(1.0 - sin2_beta) * u * ellipsoid.omega * ellipsoid.omega;
        (radial + rotation + centrifugal) / w
    }

    /// Normal gravity in mGal.
    pub fn normal_gravity_mgal(&self, latitude_deg: f64, height_m: f64) -> f64 {
        self.normal_gravity(latitude_deg, height_m) * 1e5
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// GRS80's defining values give its published normal gravity at the equator and the
    /// poles (Moritz 1988: 9.7803267715 and 9.8321863685 m/s^2).
    #[test]
    fn grs80_at_the_equator_and_the_poles() {
        assert!((GRS80.normal_gravity(0.0, 0.0) - 9.780_326_771_5).abs() < 1e-9);
        assert!((GRS80.normal_gravity(90.0, 0.0) - 9.832_186_368_5).abs() < 1e-9);
        assert!((GRS80.normal_gravity(-90.0, 0.0) - 9.832_186_368_5).abs() < 1e-9);
    }

    /// WGS84's defining values give its published normal gravity at the equator and the
    /// poles (NIMA TR8350.2 table 3.4: 9.7803253359 and 9.8321849378 m/s^2).
    #[test]
    fn wgs84_at_the_equator_and_the_poles() {
        assert!((WGS84.normal_gravity(0.0, 0.0) - 9.780_325_335_9).abs() < 1e-9);
        assert!((WGS84.normal_gravity(90.0, 0.0) - 9.832_184_937_8).abs() < 1e-9);
        // The two ellipsoids 0.14 mGal apart at 48 N (docs/formats.md 10).
        let apart = GRS80.normal_gravity_mgal(48.0, 0.0) - WGS84.normal_gravity_mgal(48.0, 0.0);
        assert!((apart - 0.14).abs() < 0.005, "{apart}");
    }

    /// Above the ellipsoid gravity falls by about 0.3086 mGal a metre.
    #[test]
    fn the_free_air_gradient() {
        let g0 = GRS80.normal_gravity_mgal(45.0, 0.0);
        let g1 = GRS80.normal_gravity_mgal(45.0, 100.0);
        assert!(
            ((g0 - g1) / 100.0 - 0.3086).abs() < 0.001,
            "{}",
            (g0 - g1) / 100.0
        );
    }
}
