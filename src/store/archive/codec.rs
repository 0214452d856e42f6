//! The archive tier's chunk codec: one tag's samples (time, value, quality code) as three
//! compressed columns. Pure: no SQL, no I/O.
//!
//! Each column is a standalone `pco` (Pcodec) stream: times as `i64` (pco finds the constant
//! 1 s step and stores the deltas of deltas in a few bits), values as `f64` (pco maps each
//! float's bits to an ordered integer, so every bit pattern — `-0.0`, subnormals, NaN payloads —
//! comes back identical) and quality codes as `u16` (nearly always a run of zeros: a few bytes).
//! Lossless by construction; [`decode`] checks lengths and time order so that a damaged blob is
//! an error, never a silently different sample.

/// The codec version stored with every chunk (`archive_chunks.codec`).
pub const CODEC_PCO_V1: i64 = 1;

/// One chunk's columns, as stored.
#[derive(Debug, Clone, PartialEq)]
pub struct Encoded {
    pub t: Vec<u8>,
    pub v: Vec<u8>,
    pub q: Vec<u8>,
}

/// One chunk's samples, decoded: parallel columns in time order.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Columns {
    pub t_ms: Vec<i64>,
    pub values: Vec<f64>,
    pub quality: Vec<u8>,
}

impl Columns {
    pub fn len(&self) -> usize {
        self.t_ms.len()
    }

    pub fn is_empty(&self) -> bool {
        self.t_ms.is_empty()
    }
}

/// Why a chunk could not be encoded or decoded.
#[derive(Debug, thiserror::Error)]
pub enum CodecError {
    #[error("archive chunk: {0}")]
    Invalid(String),
    #[error("archive chunk: pco: {0}")]
    Pco(#[from] pco::errors::PcoError),
}

fn invalid(msg: impl Into<String>) -> CodecError {
    CodecError::Invalid(msg.into())
}

/// Encodes one chunk. The columns must have the same, non-zero length and strictly
/// increasing times (one value per tag and time, as in the `samples` table).
pub fn encode(c: &Columns) -> Result<Encoded, CodecError> {
    let n = c.t_ms.len();
    if n == 0 || c.values.len() != n || c.quality.len() != n {
        return Err(invalid(format!(
            "columns of lengths {}, {}, {}",
            n,
            c.values.len(),
            c.quality.len()
        )));
    }
    if c.t_ms.windows(2).any(|w| w[1] <= w[0]) {
        return Err(invalid("times not strictly increasing"));
    }
    let level = pco::DEFAULT_COMPRESSION_LEVEL;
    let q: Vec<u16> = c.quality.iter().map(|&x| u16::from(x)).collect();
    Ok(Encoded {
        t: pco::standalone::simpler_compress(&c.t_ms, level)?,
        v: pco::standalone::simpler_compress(&c.values, level)?,
        q: pco::standalone::simpler_compress(&q, level)?,
    })
}

/// Decodes only the times of a chunk of `n` samples (what ingest needs to tell whether a
/// sample is already archived).
pub fn decode_times(t: &[u8], n: usize) -> Result<Vec<i64>, CodecError> {
    let t_ms: Vec<i64> = pco::standalone::simple_decompress(t)?;
    if t_ms.len() != n {
        return Err(invalid(format!("{} times, expected {n}", t_ms.len())));
    }
    if t_ms.windows(2).any(|w| w[1] <= w[0]) {
        return Err(invalid("times not strictly increasing"));
    }
    Ok(t_ms)
}

/// Decodes a chunk of `n` samples.
pub fn decode(e: &Encoded, n: usize) -> Result<Columns, CodecError> {
    let t_ms = decode_times(&e.t, n)?;
    let values: Vec<f64> = pco::standalone::simple_decompress(&e.v)?;
    let q: Vec<u16> = pco::standalone::simple_decompress(&e.q)?;
    if values.len() != n || q.len() != n {
        return Err(invalid(format!(
            "{} values and {} quality codes, expected {n}",
            values.len(),
            q.len()
        )));
    }
    let quality = q
        .into_iter()
        .map(|x| u8::try_from(x).map_err(|_| invalid(format!("quality code {x}"))))
        .collect::<Result<Vec<u8>, _>>()?;
    Ok(Columns {
        t_ms,
        values,
        quality,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn round_trip(c: &Columns) -> Columns {
        let e = encode(c).unwrap_or_else(|e| unreachable!("encode: {e}"));
        decode(&e, c.len()).unwrap_or_else(|e| unreachable!("decode: {e}"))
    }

    fn assert_bit_exact(a: &Columns, b: &Columns) {
        assert_eq!(a.t_ms, b.t_ms);
        assert_eq!(a.quality, b.quality);
        assert_eq!(a.values.len(), b.values.len());
        for (i, (x, y)) in a.values.iter().zip(&b.values).enumerate() {
            assert_eq!(x.to_bits(), y.to_bits(), "value {i}: {x:e} vs {y:e}");
        }
    }

    /// Irregular but strictly increasing times: 1 s steps, jitter, gaps, bursts.
    fn times(rng: &mut ChaCha8Rng, n: usize) -> Vec<i64> {
        let mut t = 1_700_000_000_000i64 + rng.random_range(-1000..1000);
        (0..n)
            .map(|_| {
                t += match rng.random_range(0..10) {
                    0 => rng.random_range(1..5),
                    1 => rng.random_range(1..10_000_000),
                    _ => 1000 + rng.random_range(-3..4),
                };
                t
            })
            .collect()
    }

    fn awkward_value(rng: &mut ChaCha8Rng, prev: f64) -> f64 {
        match rng.random_range(0..12) {
            0 => -0.0,
            1 => 0.0,
            2 => f64::from_bits(rng.random_range(1..(1u64 << 52))), // positive subnormal
            3 => -f64::from_bits(rng.random_range(1..(1u64 << 52))),
            4 => f64::MAX * rng.random_range(-1.0..1.0),
            5 => f64::MIN_POSITIVE * rng.random_range(1.0..2.0),
            6 | 7 => prev,
            8 => f64::from_bits(rng.random::<u64>() & !(0x7ffu64 << 52) | (0x3ffu64 << 52)),
            _ => rng.random_range(-1e6..1e6),
        }
    }

    #[test]
    fn random_values_round_trip_bit_exact() {
        let mut rng = ChaCha8Rng::seed_from_u64(24);
        for case in 0..200 {
            let n = match case % 4 {
                0 => 1,
                1 => rng.random_range(2..20),
                _ => rng.random_range(20..5000),
            };
            let t_ms = times(&mut rng, n);
            let mut prev = 0.0;
            let values: Vec<f64> = (0..n)
                .map(|_| {
                    prev = awkward_value(&mut rng, prev);
                    prev
                })
                .collect();
            let quality = (0..n).map(|_| rng.random_range(0..=4u8)).collect();
            let c = Columns {
                t_ms,
                values,
                quality,
            };
            assert_bit_exact(&c, &round_trip(&c));
        }
    }

    #[test]
    fn special_values_and_extreme_times_round_trip() {
        let values = vec![
            -0.0,
            0.0,
            f64::from_bits(1),
            -f64::from_bits(1),
            f64::MIN_POSITIVE,
            f64::MAX,
            f64::MIN,
            f64::EPSILON,
            1e-300,
            -1e300,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::from_bits(0x7ff8_dead_beef_0001), // a NaN with a payload
        ];
        let n = values.len();
        let c = Columns {
            // Spread over the whole i64 range, from i64::MIN up; computed in
            // i128 so the test itself cannot overflow (CI runs with overflow checks).
            t_ms: (0..n as i128)
                .map(|i| (i128::from(i64::MIN) + i * (i128::from(u64::MAX) / n as i128)) as i64)
                .collect(),
            values,
            quality: (0..n).map(|i| (i % 5) as u8).collect(),
        };
        assert_bit_exact(&c, &round_trip(&c));
    }

    #[test]
    fn a_steady_1_hz_signal_compresses_well() {
        let n = 3600;
        let c = Columns {
            t_ms: (0..n as i64)
                .map(|i| 1_700_000_000_000 + i * 1000)
                .collect(),
            values: (0..n)
                .map(|i| (7000.0 + (i as f64 * 0.01).sin() * 3.0) as f32 as f64)
                .collect(),
            quality: vec![0; n],
        };
        let e = encode(&c).unwrap_or_else(|e| unreachable!("{e}"));
        let bytes = e.t.len() + e.v.len() + e.q.len();
        assert!(bytes < n * 5, "{bytes} bytes for {n} samples");
        assert!(e.t.len() < 64, "regular times take {} bytes", e.t.len());
        assert_bit_exact(&c, &round_trip(&c));
    }

    #[test]
    fn bad_input_is_refused() {
        let c = Columns {
            t_ms: vec![2, 1],
            values: vec![0.0, 0.0],
            quality: vec![0, 0],
        };
        assert!(encode(&c).is_err());
        assert!(encode(&Columns::default()).is_err());
        let ok = Columns {
            t_ms: vec![1, 2, 3],
            values: vec![0.0, 1.0, 2.0],
            quality: vec![0, 1, 2],
        };
        let e = encode(&ok).unwrap_or_else(|e| unreachable!("{e}"));
        assert!(decode(&e, 4).is_err(), "wrong length must be an error");
        let cut = Encoded {
            v: e.v[..e.v.len() / 2].to_vec(),
            ..e.clone()
        };
        assert!(
            decode(&cut, 3).is_err(),
            "a truncated blob must be an error"
        );
    }
}
