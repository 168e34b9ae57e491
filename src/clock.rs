//! Wall-clock budgets of an invocation: `--max-hours`, and `--until HH:MM` in local time.

use crate::error::{Error, Result};

/// Checks a budget in hours (`--max-hours`): finite and positive.
pub fn check_hours(hours: f64) -> Result<f64> {
    if hours.is_finite() && hours > 0.0 {
        Ok(hours)
    } else {
        Err(Error::invalid("--max-hours", hours, "must be > 0 and finite"))
    }
}

/// The budget of a batch: `max_hours`, or the hours until the local time `until` (`HH:MM`).
pub fn budget(max_hours: Option<f64>, until: Option<&str>) -> Result<Option<f64>> {
    match (max_hours, until) {
        (Some(h), _) => check_hours(h).map(Some),
        (None, Some(t)) => hours_until(t).map(Some),
        (None, None) => Ok(None),
    }
}

/// Hours from now until the next local `HH:MM` (24-hour clock).
pub fn hours_until(hhmm: &str) -> Result<f64> {
    let now = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_secs()) as i64;
    hours_from(now, utc_offset_seconds(now), hhmm)
}

/// Hours from the Unix time `now`, in a zone `offset` seconds east of UTC, until the next `hhmm`.
fn hours_from(now: i64, offset: i64, hhmm: &str) -> Result<f64> {
    let bad = || Error::invalid("--until", hhmm, "must be HH:MM (24-hour clock)");
    let (h, m) = hhmm.split_once(':').ok_or_else(bad)?;
    let (h, m): (i64, i64) = (h.parse().map_err(|_| bad())?, m.parse().map_err(|_| bad())?);
    if !(0..24).contains(&h) || !(0..60).contains(&m) {
        return Err(bad());
    }
    let today = (now + offset).rem_euclid(86_400);
    let wait = (h * 3600 + m * 60 - today).rem_euclid(86_400);
    Ok(wait as f64 / 3600.0)
}

/// The local zone's offset from UTC at the Unix time `now`, in seconds (as `date +%z` gives it:
/// from `TZ` or the system's zone); 0 where the C library cannot tell.
#[cfg(unix)]
fn utc_offset_seconds(now: i64) -> i64 {
    let t = now as libc::time_t;
    // SAFETY: `localtime_r` writes only into `tm`, which lives across the call; a zeroed `tm` is a
    // valid value of the plain C struct.
    unsafe {
        let mut tm: libc::tm = std::mem::zeroed();
        if libc::localtime_r(&t, &mut tm).is_null() { 0 } else { tm.tm_gmtoff as i64 }
    }
}

#[cfg(not(unix))]
fn utc_offset_seconds(_now: i64) -> i64 {
    0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hours_until_counts_to_the_next_time_it_comes_round() {
        // 2024-01-01 22:30 UTC.
        let now = 1_704_148_200;
        assert_eq!(hours_from(now, 0, "23:00").unwrap(), 0.5);
        assert_eq!(hours_from(now, 0, "07:00").unwrap(), 8.5);
        assert_eq!(hours_from(now, 0, "22:30").unwrap(), 0.0);
        // 00:30 local two hours east of UTC: 07:00 is 6.5 h away.
        assert_eq!(hours_from(now, 7200, "07:00").unwrap(), 6.5);
        for bad in ["25:00", "7", "07:60", "-1:00", "ab:cd"] {
            let e = hours_from(now, 0, bad).unwrap_err().to_string();
            assert!(e.starts_with(&format!("invalid --until = {bad}:")), "{e}");
        }
    }

    #[test]
    fn the_offset_is_the_one_date_reports() {
        let now = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap().as_secs() as i64;
        let ours = utc_offset_seconds(now);
        assert!(ours.abs() <= 14 * 3600, "{ours}");
        // `date` is what this replaced; compare where it exists.
        let Ok(o) = std::process::Command::new("date").arg("+%z").output() else { return };
        let z = String::from_utf8_lossy(&o.stdout).trim().to_string();
        let (sign, digits) = if let Some(d) = z.strip_prefix('-') { (-1, d) } else { (1, z.trim_start_matches('+')) };
        if let (Some(h), Some(m)) = (digits.get(..2), digits.get(2..4)) {
            let date: i64 = sign * (h.parse::<i64>().unwrap() * 3600 + m.parse::<i64>().unwrap() * 60);
            assert_eq!(ours, date, "date +%z says {z}");
        }
    }

    #[test]
    fn budgets_are_positive_and_finite() {
        assert_eq!(budget(Some(2.0), None).unwrap(), Some(2.0));
        assert_eq!(budget(None, None).unwrap(), None);
        for h in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let e = budget(Some(h), None).unwrap_err().to_string();
            assert!(e.starts_with("invalid --max-hours = "), "{e}");
        }
    }
}
