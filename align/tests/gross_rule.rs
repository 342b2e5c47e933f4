//! How often the gross-reading rule (`align::weights::gross_readings`) flags a good
//! reading: the median absolute deviation of a station's few readings can be small by
//! chance, so "10 robust sds" is far likelier than a normal's 10 sds (docs/model.md 6.1).

use align::weights::gross_readings;

/// Stations of `n` standard normal readings, the floor `floor`: how many have a good
/// reading flagged.
fn flagged(stations: usize, n: usize, floor: f64) -> usize {
    let mut rng = fixtures::rng::Rng::new(20_261_128, "gross rule");
    let mut flagged = 0usize;
    for _ in 0..stations {
        let dz: Vec<f64> = (0..n).map(|_| rng.normal()).collect();
        flagged += usize::from(gross_readings(&dz, floor).iter().any(|&g| g));
    }
    flagged
}

/// Of 100 000 stations of 14 readings (esgt-2005's), those whose own spread sets the scale
/// (no floor) flag a good reading in about 5e-4 (4.6e-4 here; asserted between 2e-4 and
/// 1e-3, about 4 binomial sds either side); with the floor at the readings' own sd, in none.
/// Printed for the record.
#[test]
fn the_gross_rule_flags_few_good_readings() {
    let stations = 100_000;
    let own = flagged(stations, 14, 0.0) as f64 / stations as f64;
    let floored = flagged(stations, 14, 1.0);
    eprintln!(
        "gross rule, {stations} stations of 14 good readings: a reading flagged in {own:.1e} of them without a floor, {floored} with the floor at their sd"
    );
    assert!((2e-4..1e-3).contains(&own), "{own}");
    assert_eq!(floored, 0);
}
