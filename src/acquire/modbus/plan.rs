//! The poll plan (which requests to make, with the tag id of each field) and the pure step
//! from register words to samples: decoding, the per-field range policy and the plant clock.
//! No I/O.

use crate::acquire::register_map::{
    decode_field, FieldSpec, ModbusConfig, ReadingStatus, RegisterKind,
};
use crate::quality::Quality;
use crate::store::{Sample, TagId};

/// One request of the poll plan, with the tag id of each field.
#[derive(Debug, Clone)]
pub struct PlannedRequest {
    pub slave: u8,
    pub kind: RegisterKind,
    pub start: u16,
    pub count: u16,
    pub fields: Vec<(TagId, FieldSpec)>,
}

/// What the poll loop reads, in order. Built from a checked register map.
#[derive(Debug, Clone)]
pub struct PollPlan {
    pub endpoint: String,
    pub requests: Vec<PlannedRequest>,
    /// The bad-value policy applied to every polled value (`[quality]`).
    pub quality: crate::quality::QualityConfig,
}

impl PollPlan {
    /// `tags` holds the tag id of every field in map order ([`ModbusConfig::fields`]).
    /// The map must have passed `check()`; addresses are then within u16.
    pub fn new(map: &ModbusConfig, tags: &[TagId]) -> Result<PollPlan, String> {
        let mut ids = tags.iter().copied();
        let mut requests = Vec::new();
        for (i, r) in map.requests.iter().enumerate() {
            let start = u16::try_from(r.start_address)
                .map_err(|_| format!("modbus.request[{i}].start_address out of range"))?;
            let count = u16::try_from(r.register_count())
                .map_err(|_| format!("modbus.request[{i}] register count out of range"))?;
            let mut fields = Vec::new();
            for f in &r.fields {
                let id = ids
                    .next()
                    .ok_or_else(|| "fewer tag ids than fields".to_string())?;
                fields.push((id, f.clone()));
            }
            requests.push(PlannedRequest {
                slave: r.slave_id,
                kind: r.register,
                start,
                count,
                fields,
            });
        }
        Ok(PollPlan {
            endpoint: map.endpoint.clone(),
            requests,
            quality: crate::quality::QualityConfig::default(),
        })
    }

    pub fn tag_count(&self) -> usize {
        self.requests.iter().map(|r| r.fields.len()).sum()
    }
}

fn quality(status: ReadingStatus) -> Quality {
    match status {
        ReadingStatus::Good => Quality::Good,
        ReadingStatus::OutOfRange => Quality::OutOfRange,
        ReadingStatus::NotFinite => Quality::Bad,
    }
}

/// The plant clock of one poll: the value of `tag` among the decoded samples, as epoch ms.
pub(super) fn plant_clock(batch: &[Sample], tag: TagId) -> Result<i64, String> {
    let Some(s) = batch.iter().find(|s| s.tag == tag) else {
        return Err("plant clock field missing from the poll".into());
    };
    // Between 1970 and 2262 (i64 nanoseconds elsewhere); anything else is not a clock.
    if s.quality != Quality::Good || !(s.value.is_finite() && (0.0..9.2e15).contains(&s.value)) {
        return Err(format!(
            "plant clock field holds an invalid time ({} ms)",
            s.value
        ));
    }
    Ok(s.value.round() as i64)
}

/// The bad-value policy's range check (`crate::quality`) for a field: the register map's own
/// `min`/`max` when it sets either (the per-tag override), else the signal's default range.
fn policy_quality(f: &crate::acquire::register_map::FieldSpec, value: f64, q: Quality) -> Quality {
    if q != Quality::Good || f.min.is_some() || f.max.is_some() {
        return q;
    }
    let limits = f.signal.map(crate::quality::default_limits);
    crate::quality::classify_value(value, limits.as_ref())
}

/// Decodes one request's registers into samples (pure; flagged values keep their quality).
pub fn decode_request(req: &PlannedRequest, words: &[u16], t_ms: i64, out: &mut Vec<Sample>) {
    for (tag, f) in &req.fields {
        let sample = match decode_field(f, u32::from(req.start), words) {
            Ok(r) => Sample {
                tag: *tag,
                t_ms,
                // SQLite cannot store NaN (it becomes NULL); a Bad sample keeps 0 as value and
                // its quality says the number is meaningless.
                value: if r.value.is_finite() { r.value } else { 0.0 },
                quality: policy_quality(f, r.value, quality(r.status)),
            },
            Err(_) => Sample {
                tag: *tag,
                t_ms,
                value: 0.0,
                quality: Quality::Bad,
            },
        };
        out.push(sample);
    }
}
