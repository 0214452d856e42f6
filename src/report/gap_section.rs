//! The report's "Model–plant gap" section: the stored gap analyses (`gtwatch gap --segment`)
//! of the period — which start-ups the model did not fit, what the analysis named as the
//! cause, how far adding it shrank the gap. Pure HTML building from stored rows.

use crate::chart::esc;
use crate::store::GapAnalysisRow;
use crate::time::fmt_ms;
use std::fmt::Write;

/// Rows shown at most.
pub(super) const MAX_ROWS: usize = 50;

/// The section's HTML.
pub(super) fn render(rows: &[GapAnalysisRow]) -> String {
    let mut h = String::from("<h2>Model–plant gap</h2>");
    if rows.is_empty() {
        h.push_str(
            "<p class=\"meta\">No gap analysis stored for this period \
             (<code>gtwatch gap --segment ID</code> runs one on a stored start-up).</p>",
        );
        return h;
    }
    let named = rows
        .iter()
        .filter(|r| crate::gap::names_effect(&r.effect))
        .count();
    let unexplained = rows.iter().filter(|r| r.effect == "unexplained").count();
    let ambiguous = rows.iter().filter(|r| r.effect == "ambiguous").count();
    let _ = write!(
        h,
        "<p class=\"meta\">{} analysis(es): {named} named an unmodelled effect, {unexplained} \
         found a gap no library effect explains, {ambiguous} ambiguous: an input instrument \
         (fuel meter, T1, P1, power; listed) could hide behind the health, so its values are not \
         to be trusted alone. An effect adopted into the engine file \
         (<code>gtwatch gap --adopt</code>) is used by every later diagnosis.</p>\
         <table><tr><th class=\"l\">start-up (UTC)</th><th>segment</th><th class=\"l\">baseline fit</th>\
         <th>normalised residual</th><th class=\"l\">verdict</th><th>shrinkage</th><th>confidence</th></tr>",
        rows.len()
    );
    for r in rows {
        let _ = write!(
            h,
            "<tr><td class=\"l\">{}</td><td>{}</td><td class=\"l\">{}</td><td>{:.2}</td>\
             <td class=\"l\">{}</td><td>{:.0} %</td><td>{:.2}</td></tr>",
            esc(&fmt_ms(r.segment_start_ms)),
            r.segment_id,
            esc(&r.baseline_fit_quality),
            r.normalised_residual,
            esc(&match (&r.doubted, r.aliases.is_empty()) {
                (Some(d), _) => format!(
                    "{} ({d} explains it but needs a less plausible health; instrument: {})",
                    r.effect,
                    r.aliases.join(", ")
                ),
                (None, true) => r.effect.clone(),
                (None, false) => format!("{} (instrument: {})", r.effect, r.aliases.join(", ")),
            }),
            100.0 * r.shrinkage,
            r.confidence
        );
    }
    h.push_str("</table>");
    h
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_section_lists_each_analysis_and_counts_the_verdicts() {
        let row = |id, effect: &str| GapAnalysisRow {
            id,
            segment_id: 10 + id,
            holdout_segment_id: None,
            effect: effect.into(),
            shrinkage: 0.62,
            confidence: 0.4,
            baseline_fit_quality: "suspect".into(),
            normalised_residual: 1.35,
            created_at_ms: 0,
            segment_start_ms: 1_767_571_200_000,
            aliases: if effect == "ambiguous" {
                vec!["fuel_meter".into()]
            } else {
                Vec::new()
            },
            doubted: None,
        };
        let h = render(&[
            row(1, "sensor_lag:t34_k"),
            row(2, "unexplained"),
            row(3, "none"),
            row(4, "ambiguous"),
        ]);
        assert!(h.contains("4 analysis(es): 1 named an unmodelled effect, 1 found a gap"));
        assert!(h.contains("1 ambiguous"));
        assert!(h.contains("ambiguous (instrument: fuel_meter)"), "{h}");
        let doubted = GapAnalysisRow {
            doubted: Some("fuel_meter_offset".into()),
            ..row(5, "ambiguous")
        };
        assert!(
            render(&[doubted]).contains(
                "ambiguous (fuel_meter_offset explains it but needs a less plausible health; \
                 instrument: fuel_meter)"
            ),
            "the doubted candidate is shown"
        );
        assert_eq!(h.matches("<tr>").count(), 5, "header and four rows");
        assert!(h.contains("sensor_lag:t34_k") && h.contains("62 %"));
        assert!(h.contains("2026-01-05"));
        assert!(render(&[]).contains("No gap analysis stored"));
    }
}
