//! Where an adaptation curve's knots go and how many the data carry: evenly spaced from a
//! component's lowest relative speed towards the design anchor, at least
//! [`MIN_KNOT_SPACING`] apart, one fewer than the distinct speeds the data hold.
//! Pure arithmetic on speeds; must not fit or touch an engine.

/// `count` knots evenly spaced from `lo` towards the design speed (the anchor excluded).
pub(super) fn knots(lo: f64, count: usize) -> Vec<f64> {
    (0..count)
        .map(|i| lo + i as f64 * (1.0 - lo) / count as f64)
        .collect()
}

/// Least spacing of knots (relative speed): the engine file refuses a knot within 0.01 of the
/// design anchor, and [`knots`] puts the last one a spacing below it.
pub(super) const MIN_KNOT_SPACING: f64 = 0.015;

/// The most knots [`knots`] can spread from `lo` with [`MIN_KNOT_SPACING`] (at least 1).
pub(super) fn knots_that_fit(lo: f64) -> usize {
    (((1.0 - lo) / MIN_KNOT_SPACING).floor() as usize).max(1)
}

/// Distinct speeds (to 0.005) below 0.99 in `speeds`.
pub(super) fn distinct_speeds(speeds: &[f64]) -> usize {
    let mut v: Vec<i64> = speeds
        .iter()
        .filter(|s| **s < 0.99)
        .map(|s| (s / 0.005).round() as i64)
        .collect();
    v.sort_unstable();
    v.dedup();
    v.len()
}

/// How many knots a component's data can carry, and what sets it: one fewer than its
/// `distinct` speeds below the design speed (at least 1), at most `max`, and no more than fit
/// [`MIN_KNOT_SPACING`] apart from `lo` (its lowest speed) up to the anchor.
pub(super) fn knot_limit(distinct: usize, lo: f64, max: usize) -> (usize, String) {
    let by_data = distinct.saturating_sub(1).max(usize::from(distinct > 0));
    let by_spacing = knots_that_fit(lo);
    let n = by_data.min(max).min(by_spacing);
    let why = if n == by_data {
        format!("one fewer than the data's {distinct} distinct speeds below the design speed")
    } else if n == max {
        format!(
            "the most a curve gets (the data's {distinct} distinct speeds below the design \
             speed would carry {by_data})"
        )
    } else {
        format!(
            "as many as fit {MIN_KNOT_SPACING} apart between the lowest speed {lo:.3} and the \
             design anchor"
        )
    };
    (n, why)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn knots_spread_from_the_lowest_speed_towards_design() {
        assert_eq!(knots(0.7, 1), vec![0.7]);
        let k = knots(0.7, 3);
        assert!((k[1] - 0.8).abs() < 1e-12 && (k[2] - 0.9).abs() < 1e-12);
    }

    #[test]
    fn knots_keep_clear_of_the_design_anchor() {
        // Data from 0.95 up: 6 knots would put the last at 0.9917, which the engine file
        // refuses (within 0.01 of the anchor).
        let n = knots_that_fit(0.95);
        assert_eq!(n, 3);
        let k = knots(0.95, n);
        assert!(
            k.iter().all(|x| 1.0 - x >= MIN_KNOT_SPACING - 1e-12),
            "{k:?}"
        );
        assert_eq!(knots_that_fit(0.969), 2);
        assert_eq!(knots_that_fit(0.99), 1);
    }

    #[test]
    fn knot_count_follows_the_distinct_speeds() {
        let count = |v: &[f64], max| knot_limit(distinct_speeds(v), v[0], max).0;
        assert_eq!(count(&[0.7, 0.8, 0.9, 1.0], 4), 2);
        assert_eq!(count(&[0.7, 0.7, 1.0], 4), 1);
        assert_eq!(count(&[0.6, 0.65, 0.7, 0.75, 0.8, 0.85, 0.9, 1.0], 4), 4);
        assert_eq!(knot_limit(0, 1.0, 4).0, 0);
        // The reason names what set the count.
        assert!(knot_limit(3, 0.7, 4)
            .1
            .contains("one fewer than the data's 3"));
        assert!(knot_limit(9, 0.7, 4).1.starts_with("the most a curve gets"));
        assert!(knot_limit(9, 0.95, 6)
            .1
            .contains("apart between the lowest speed 0.950"));
    }
}
