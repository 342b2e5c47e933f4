//! A value with its sigma, printed to the sigma's precision (GUM, JCGM 100:2008, 7.2.6): the
//! sigma to two significant digits, the value to the same decimal place. Every stage that
//! prints a fitted parameter (the console, the report, report.md) prints it through here,
//! so that a value copied from any of them is within 0.053 sigma of the fit's, and no digit
//! beyond the sigma's second is printed.

/// The decimal place of a sigma's second significant digit (the value's last digit is at
/// `10^place`), from the sigma rounded to two digits (0.0996 is 0.10, place -2).
fn last_place(sigma: f64) -> i32 {
    two_significant(sigma).log10().floor() as i32 - 1
}

/// `sigma` rounded to two significant digits, as `{:.1e}` rounds it (the one rounding every
/// notation here prints).
fn two_significant(sigma: f64) -> f64 {
    format!("{sigma:.1e}").parse().unwrap_or(sigma)
}

/// `value` and `sigma` as two strings in the same notation, the value to the sigma's second
/// significant digit: fixed where the value is under a million and the place not below
/// 10^-6 (`-12.346`, `0.023`), else scientific with the value's exponent (`2.43017302e-1`,
/// `3.6e-8`). A sigma that is not a positive number leaves the value at 7 digits.
pub fn rounded_to_sigma(value: f64, sigma: f64) -> (String, String) {
    if !(sigma.is_finite() && sigma > 0.0 && value.is_finite()) {
        return (format!("{value:.6e}"), format!("{sigma:e}"));
    }
    let place = last_place(sigma);
    let sigma = two_significant(sigma);
    let magnitude = if value == 0.0 {
        place
    } else {
        value.abs().log10().floor() as i32
    };
    if magnitude < 6 && place >= -6 {
        // Above the units, the digits below the place are zeros (1230, not 1234.5).
        let (value, sigma) = if place > 0 {
            let unit = 10f64.powi(place);
            ((value / unit).round() * unit, (sigma / unit).round() * unit)
        } else {
            (value, sigma)
        };
        let decimals = usize::try_from(-place).unwrap_or(0);
        return (
            without_negative_zero(format!("{value:.decimals$}")),
            format!("{sigma:.decimals$}"),
        );
    }
    let exponent = magnitude.max(place + 1);
    let decimals = usize::try_from(exponent - place).unwrap_or(0);
    let mantissa = value / 10f64.powi(exponent);
    (
        without_negative_zero(format!("{mantissa:.decimals$}e{exponent}")),
        format!("{sigma:.1e}"),
    )
}

/// `value +/- sigma` to the sigma's precision ([`rounded_to_sigma`]).
pub fn value_with_sigma(value: f64, sigma: f64) -> String {
    let (v, s) = rounded_to_sigma(value, sigma);
    format!("{v} +/- {s}")
}

/// A sd or a sigma alone, to two significant digits, in [`rounded_to_sigma`]'s notation.
pub fn two_digits(sigma: f64) -> String {
    rounded_to_sigma(sigma, sigma).1
}

/// "-0.00" (a negative value rounded to zero) as "0.00": a sign the digits do not carry.
pub fn without_negative_zero(s: String) -> String {
    match s.strip_prefix('-') {
        Some(rest)
            if rest
                .split('e')
                .next()
                .is_some_and(|m| m.chars().all(|c| matches!(c, '0' | '.'))) =>
        {
            rest.to_owned()
        }
        _ => s,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_value_stops_at_the_sigmas_second_digit() {
        assert_eq!(
            rounded_to_sigma(-12.345_678, 0.023_4),
            ("-12.346".into(), "0.023".into())
        );
        assert_eq!(
            rounded_to_sigma(0.243_017_302_4, 3.55e-8),
            ("2.43017302e-1".into(), "3.6e-8".into())
        );
        assert_eq!(
            rounded_to_sigma(1234.5, 230.0),
            ("1230".into(), "230".into())
        );
        assert_eq!(
            rounded_to_sigma(0.5, 0.0996),
            ("0.50".into(), "0.10".into())
        );
        assert_eq!(
            rounded_to_sigma(-0.000_1, 0.02),
            ("0.000".into(), "0.020".into())
        );
        assert_eq!(
            rounded_to_sigma(2.5e7, 1.2e3),
            ("2.50000e7".into(), "1.2e3".into())
        );
        assert_eq!(value_with_sigma(1.0, 0.0), "1.000000e0 +/- 0e0");
        assert_eq!(two_digits(0.012_34), "0.012");
        assert_eq!(two_digits(3.55e-8), "3.6e-8");
        assert_eq!(two_digits(2.46e-4), "0.00025");
        assert_eq!(without_negative_zero("-0.0e-3".into()), "0.0e-3");
        assert_eq!(without_negative_zero("-0.01".into()), "-0.01");
    }

    /// Whatever the scale, the printed value is within 0.053 sigma of the value (half a unit
    /// of the second digit of a sigma rounded up by at most 5 %), and the printed sigma
    /// within 5 % of the sigma (two digits of 1.05 are 1.1).
    #[test]
    fn a_printed_value_is_within_a_twentieth_of_its_sigma() {
        let mut x = 0.123_456_789_f64;
        for step in 0..400 {
            let value = x * 10f64.powi(step % 17 - 8) * if step % 3 == 0 { -1.0 } else { 1.0 };
            let sigma =
                (x * 7.3).fract().max(0.011) * 10f64.powi(step % 13 - 9) * value.abs().max(1e-12);
            let (v, s) = rounded_to_sigma(value, sigma);
            let (v, s): (f64, f64) = (v.parse().expect(&v), s.parse().expect(&s));
            assert!((v - value).abs() <= 0.053 * sigma, "{value} {sigma}: {v}");
            assert!((s / sigma - 1.0).abs() <= 0.05 + 1e-9, "{sigma}: {s}");
            x = (x * 9.87 + 0.31).fract();
        }
    }
}
