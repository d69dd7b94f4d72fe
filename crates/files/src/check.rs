//! The one wording of a number's check, for every file pneuflex reads (scenes, component sheets, rig
//! files): each reader blames the message on its file, line and key. The `no_std` control crate words its
//! parameter errors the same way (`pneuflex_control::ParamError`).

/// A finite number: `must be a finite number, got inf`.
pub fn finite(x: f64) -> Result<f64, String> {
    if x.is_finite() {
        Ok(x)
    } else {
        Err(format!("must be a finite number, got {x}"))
    }
}

/// A finite number >= 0: `must be >= 0, got -1`.
pub fn non_negative(x: f64) -> Result<f64, String> {
    finite(x)?;
    if x >= 0.0 {
        Ok(x)
    } else {
        Err(format!("must be >= 0, got {x}"))
    }
}

/// A finite number > 0: `must be > 0, got 0`.
pub fn positive(x: f64) -> Result<f64, String> {
    finite(x)?;
    if x > 0.0 {
        Ok(x)
    } else {
        Err(format!("must be > 0, got {x}"))
    }
}

/// A finite number in `[lo, hi]`: `must be in [-90, 90], got 95` (`unit`, when not empty, follows the
/// interval: `must be in [-90, 90] degrees below the horizontal, got 95`).
pub fn within(x: f64, lo: f64, hi: f64, unit: &str) -> Result<f64, String> {
    finite(x)?;
    if (lo..=hi).contains(&x) {
        Ok(x)
    } else if unit.is_empty() {
        Err(format!("must be in [{lo}, {hi}], got {x}"))
    } else {
        Err(format!("must be in [{lo}, {hi}] {unit}, got {x}"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_check_words_its_refusal_once() {
        assert_eq!(
            finite(f64::NAN).unwrap_err(),
            "must be a finite number, got NaN"
        );
        assert_eq!(non_negative(-1.0).unwrap_err(), "must be >= 0, got -1");
        assert_eq!(positive(0.0).unwrap_err(), "must be > 0, got 0");
        assert_eq!(
            positive(f64::INFINITY).unwrap_err(),
            "must be a finite number, got inf"
        );
        assert_eq!(
            within(95.0, -90.0, 90.0, "").unwrap_err(),
            "must be in [-90, 90], got 95"
        );
        assert_eq!(within(90.0, -90.0, 90.0, "").unwrap(), 90.0);
    }
}
