//! The down component of an antenna array's session from the specific force's magnitude
//! (docs/model.md 7, "An antenna array"): f_D = -sqrt(|f|^2 - |h|^2), |f| each sample's
//! own (no attitude enters it) and h the horizontal force the track gives
//! ([`horizontal::track_force`]), so that the array's tilt error, a few mrad an epoch,
//! does not reach down. Turned by that attitude instead, down errs by g eps^2 / 2 (12 mGal
//! an epoch at 5 mrad) and by eps times the horizontal force.
//!
//! The track's force is low-passed where the positions' noise, differentiated twice,
//! stays under what the attitude's would give: the noise densities s_p^2 (2 pi f)^4 and
//! g^2 s_eps^2 meet at f = sqrt(g s_eps / s_p) / (2 pi), 0.35 Hz for 1 cm and 5 mrad.
//! What the vehicle's horizontal force holds above that cut-off is not seen; its mean
//! square over 2 g is what down would lose.

use super::GravityError;
use super::horizontal;
use super::reduce::Stretch;
use ingest::contract::gravity_ledger::AntennasUsed;

/// Gravity the cut-off is computed with, m/s^2.
const G_M_S2: f64 = 9.8;

/// The cut-off of the track's horizontal force for an array whose solved epochs have
/// these median sds, positions `white_m` (north, east, up) white per epoch, at epochs `dt`
/// s apart: where the positions' differentiated noise meets the tilt's, within [0.01 Hz, a
/// quarter of the epochs' rate]. None for an array without roll (two antennas).
pub fn cutoff_hz(used: &AntennasUsed, white_m: [f64; 3], dt: f64) -> Option<f64> {
    let [_, pitch, roll] = used.median_sd_hpr_deg;
    let tilt = (pitch?.to_radians().hypot(roll?.to_radians())) / 2f64.sqrt();
    let [n, e, _] = used.median_sd_position_m;
    let position = n.max(white_m[0]).hypot(e.max(white_m[1])) / 2f64.sqrt();
    let f = (G_M_S2 * tilt / position.max(1e-4)).sqrt() / std::f64::consts::TAU;
    Some(f.clamp(0.01, 0.25 / dt))
}

/// `s`'s down force formed again from the epochs' magnitudes `norm_mgal` and the track's
/// horizontal force low-passed at `cutoff_hz`, less the variance its positions' white sds
/// north and east (`var_ne_m2`, their squares summed) put into |h|^2 (its mean, which
/// would otherwise bias down by var / 2 g); what that error's square does about its mean,
/// a white error per epoch of sd s^2 sqrt(sum_m R(m)^2) / |f| (two axes of sd s each:
/// [`horizontal::TrackForce`]), into `s.sd_force_mgal`.
pub fn form_down(
    s: &mut Stretch,
    norm_mgal: &[f64],
    var_ne_m2: &[f64],
    (dt, cutoff_hz): (f64, f64),
) -> Result<(), GravityError> {
    let h = horizontal::track_force(s, dt, cutoff_hz)?;
    s.sd_force_mgal.clear();
    for (k, f) in s.f_down_mgal.iter_mut().enumerate() {
        let h2 =
            h.f_mgal[0][k].powi(2) + h.f_mgal[1][k].powi(2) - h.gain_mgal2_per_m2 * var_ne_m2[k];
        *f = -(norm_mgal[k].powi(2) - h2).max(0.0).sqrt();
        // |dh|^2 / 2 |f| about its mean: two axes of sd^2 = var / 2 each.
        let sd = 0.5 * var_ne_m2[k] * h.square_gain_mgal2_per_m2 / norm_mgal[k].max(1.0);
        s.sd_force_mgal.push(sd);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gravity::filter::Lowpass;
    use crate::gravity::reduce;
    use ingest::contract::survey::FilterKind;

    /// A still triad whose positions err white, 1 cm north and east at 10 Hz: down formed
    /// from the magnitude keeps the true force's mean (the squared error's mean taken out,
    /// within a hundredth of a mGal), and through a 100 s filter its error's sd is the
    /// sigma part `sd_force_mgal` gives, within 10 % over 40 draws of a 2000 s stretch.
    #[test]
    fn the_squared_position_error_is_taken_out_and_its_sigma_honest() {
        let (dt, n, sd) = (0.1, 20_000, 0.01);
        let g = 980_000.0;
        let (sections, pad) = (
            Lowpass::design(FilterKind::Butterworth, 0.01, 1.0 / dt).expect("filter"),
            reduce::padding(100.0, dt),
        );
        let noise_row = reduce::row(&sections, reduce::reach(100.0, dt), None);
        let (mut mean, mut square, mut count) = (0.0, 0.0, 0.0);
        let mut predicted = 0.0;
        for draw in 0..40 {
            let mut rng = fixtures::rng::Rng::new(draw, "magnitude");
            let mut s = Stretch::default();
            for k in 0..n {
                s.time_gps_ns.push(k as i64 * 100_000_000);
                s.latitude_deg
                    .push(45.0 + (sd * rng.normal() / 6_367_000.0).to_degrees());
                s.longitude_deg
                    .push(5.0 + (sd * rng.normal() / 4_517_000.0).to_degrees());
                s.height_m.push(0.0);
                s.f_down_mgal.push(-g);
            }
            let var = vec![2.0 * sd * sd; n];
            form_down(&mut s, &vec![g; n], &var, (dt, 0.35)).expect("formed");
            let error: Vec<f64> = s.f_down_mgal.iter().map(|f| f + g).collect();
            let filtered = sections.apply(&error, pad, (100.0 / dt) as usize);
            for e in &filtered[n / 4..3 * n / 4] {
                mean += e;
                square += e * e;
                count += 1.0;
            }
            predicted = reduce::scaled(&noise_row, &s.sd_force_mgal)[n / 2];
        }
        let mean = mean / count;
        let sd_seen = (square / count - mean * mean).sqrt();
        eprintln!("mean {mean:.4} mGal, sd {sd_seen:.4} against {predicted:.4} mGal");
        assert!(mean.abs() < 0.01, "{mean}");
        assert!(
            (sd_seen / predicted - 1.0).abs() < 0.1,
            "{sd_seen} {predicted}"
        );
    }
}
