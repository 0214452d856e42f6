//! Tests of the register map: codec vectors (hand-computed words for every type and byte
//! order), round trips, and validation messages.

use super::check::modicon_hint;
use super::*;
use crate::config_problem::ConfigProblem;

const ORDERS: [ByteOrder; 4] = [
    ByteOrder::ABCD,
    ByteOrder::CDAB,
    ByteOrder::BADC,
    ByteOrder::DCBA,
];

fn field(name: &str, address: u32, ty: DataType) -> FieldSpec {
    FieldSpec {
        name: name.into(),
        address,
        data_type: ty,
        byte_order: ByteOrder::ABCD,
        scale: 1.0,
        offset: 0.0,
        unit: String::new(),
        signal: None,
        min: None,
        max: None,
    }
}

/// (type, order, wire words, expected raw value), all hand-computed.
fn vectors() -> Vec<(DataType, ByteOrder, Vec<u16>, f64)> {
    use ByteOrder::*;
    use DataType::*;
    vec![
        // u16 0x1234 = 4660; the byte-swapping orders read 0x3412.
        (U16, ABCD, vec![0x1234], 4660.0),
        (U16, CDAB, vec![0x1234], 4660.0),
        (U16, BADC, vec![0x3412], 4660.0),
        (U16, DCBA, vec![0x3412], 4660.0),
        // i16 -300 = 0xFED4.
        (I16, ABCD, vec![0xFED4], -300.0),
        (I16, CDAB, vec![0xFED4], -300.0),
        (I16, BADC, vec![0xD4FE], -300.0),
        (I16, DCBA, vec![0xD4FE], -300.0),
        // u32 0x12345678 = 305419896.
        (U32, ABCD, vec![0x1234, 0x5678], 305_419_896.0),
        (U32, CDAB, vec![0x5678, 0x1234], 305_419_896.0),
        (U32, BADC, vec![0x3412, 0x7856], 305_419_896.0),
        (U32, DCBA, vec![0x7856, 0x3412], 305_419_896.0),
        // i32 -2 = 0xFFFFFFFE.
        (I32, ABCD, vec![0xFFFF, 0xFFFE], -2.0),
        (I32, CDAB, vec![0xFFFE, 0xFFFF], -2.0),
        (I32, BADC, vec![0xFFFF, 0xFEFF], -2.0),
        (I32, DCBA, vec![0xFEFF, 0xFFFF], -2.0),
        // i32 -123456789 = 0xF8A432EB.
        (I32, ABCD, vec![0xF8A4, 0x32EB], -123_456_789.0),
        (I32, CDAB, vec![0x32EB, 0xF8A4], -123_456_789.0),
        (I32, BADC, vec![0xA4F8, 0xEB32], -123_456_789.0),
        (I32, DCBA, vec![0xEB32, 0xA4F8], -123_456_789.0),
        // f32 -12.5 = 0xC1480000.
        (F32, ABCD, vec![0xC148, 0x0000], -12.5),
        (F32, CDAB, vec![0x0000, 0xC148], -12.5),
        (F32, BADC, vec![0x48C1, 0x0000], -12.5),
        (F32, DCBA, vec![0x0000, 0x48C1], -12.5),
        // f32 1234.5678 ≈ 0x449A522B (f32 rounding: 1234.5677490234375).
        (F32, ABCD, vec![0x449A, 0x522B], 1_234.567_749_023_437_5),
        (F32, DCBA, vec![0x2B52, 0x9A44], 1_234.567_749_023_437_5),
        // f64 1.5 = 0x3FF8000000000000.
        (F64, ABCD, vec![0x3FF8, 0, 0, 0], 1.5),
        (F64, CDAB, vec![0, 0, 0, 0x3FF8], 1.5),
        (F64, BADC, vec![0xF83F, 0, 0, 0], 1.5),
        (F64, DCBA, vec![0, 0, 0, 0xF83F], 1.5),
        // f64 -2.25 = 0xC002000000000000; and 0x40934A4560000000 = 1234.5677490234375.
        (F64, ABCD, vec![0xC002, 0, 0, 0], -2.25),
        (F64, CDAB, vec![0x0000, 0x0000, 0x0000, 0xC002], -2.25),
        (
            F64,
            ABCD,
            vec![0x4093, 0x4A45, 0x6000, 0x0000],
            1_234.567_749_023_437_5,
        ),
        (
            F64,
            CDAB,
            vec![0x0000, 0x6000, 0x4A45, 0x4093],
            1_234.567_749_023_437_5,
        ),
        (
            F64,
            BADC,
            vec![0x9340, 0x454A, 0x0060, 0x0000],
            1_234.567_749_023_437_5,
        ),
        (
            F64,
            DCBA,
            vec![0x0000, 0x0060, 0x454A, 0x9340],
            1_234.567_749_023_437_5,
        ),
    ]
}

#[test]
fn every_type_and_byte_order_decodes_hand_computed_words() {
    for (ty, order, words, want) in vectors() {
        let got = decode_raw(&words, ty, order).expect("enough words");
        assert_eq!(got, want, "{ty} {order:?} {words:04X?}");
    }
}

#[test]
fn encode_is_the_inverse_of_decode() {
    for (ty, order, words, want) in vectors() {
        assert_eq!(encode_raw(want, ty, order), words, "{ty} {order:?}");
    }
    // Distinct bytes make every permutation visible: 0x0102030405060708 as f64 bits.
    let v = f64::from_bits(0x0102_0304_0506_0708);
    let expect = [
        vec![0x0102, 0x0304, 0x0506, 0x0708],
        vec![0x0708, 0x0506, 0x0304, 0x0102],
        vec![0x0201, 0x0403, 0x0605, 0x0807],
        vec![0x0807, 0x0605, 0x0403, 0x0201],
    ];
    for (order, words) in ORDERS.iter().zip(expect) {
        assert_eq!(encode_raw(v, DataType::F64, *order), words, "{order:?}");
        assert_eq!(
            decode_raw(&words, DataType::F64, *order).map(f64::to_bits),
            Ok(0x0102_0304_0506_0708)
        );
    }
}

#[test]
fn integer_encoding_rounds_and_saturates() {
    assert_eq!(
        encode_raw(70000.0, DataType::U16, ByteOrder::ABCD),
        vec![0xFFFF]
    );
    assert_eq!(encode_raw(-5.0, DataType::U16, ByteOrder::ABCD), vec![0]);
    assert_eq!(
        encode_raw(-40000.0, DataType::I16, ByteOrder::ABCD),
        vec![0x8000]
    );
    assert_eq!(encode_raw(2.6, DataType::I16, ByteOrder::ABCD), vec![3]);
    assert_eq!(
        encode_raw(f64::NAN, DataType::U32, ByteOrder::ABCD),
        vec![0, 0]
    );
}

#[test]
fn short_reads_are_errors() {
    assert_eq!(
        decode_raw(&[1], DataType::F32, ByteOrder::ABCD),
        Err(ShortRead {
            data_type: DataType::F32,
            needed: 2,
            got: 1
        })
    );
    let f = field("x", 11, DataType::F64);
    assert!(decode_field(&f, 10, &[0, 0, 0]).is_err());
    assert!(decode_field(&f, 10, &[0, 0, 0, 0, 0]).is_ok());
}

#[test]
fn scale_offset_and_range() {
    let mut f = field("t2", 10, DataType::U16);
    f.scale = 0.1;
    f.offset = 273.15;
    f.min = Some(250.0);
    f.max = Some(900.0);
    // 0x0FA0 = 4000 → 400.0 + 273.15
    let r = decode_field(&f, 8, &[0, 0, 0x0FA0]).expect("decode");
    assert!((r.value - 673.15).abs() < 1e-9);
    assert_eq!(r.status, ReadingStatus::Good);
    // 0xFFFF = 65535 → 6553.5 + 273.15: a classic "sensor fault" fill value, out of range.
    let r = decode_field(&f, 10, &[0xFFFF]).expect("decode");
    assert_eq!(r.status, ReadingStatus::OutOfRange);
    let r = decode_field(&f, 10, &[0]).expect("decode");
    assert_eq!(r.status, ReadingStatus::Good); // 273.15 ≥ 250
    f.offset = 0.0;
    let r = decode_field(&f, 10, &[0]).expect("decode");
    assert_eq!(r.status, ReadingStatus::OutOfRange); // 0 < 250
                                                     // Encoding goes back through scale and offset.
    f.offset = 273.15;
    assert_eq!(encode_field(&f, 673.15), vec![4000]);
}

#[test]
fn nan_and_infinity_are_not_finite_for_both_float_widths() {
    let f32f = field("x", 0, DataType::F32);
    let f64f = field("y", 0, DataType::F64);
    for order in ORDERS {
        let mut a = f32f.clone();
        a.byte_order = order;
        let mut b = f64f.clone();
        b.byte_order = order;
        for v in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let r = decode_field(&a, 0, &encode_field(&a, v)).expect("decode");
            assert_eq!(r.status, ReadingStatus::NotFinite, "f32 {order:?} {v}");
            let r = decode_field(&b, 0, &encode_field(&b, v)).expect("decode");
            assert_eq!(r.status, ReadingStatus::NotFinite, "f64 {order:?} {v}");
        }
    }
    // 0x7FC0_0000 is the canonical f32 quiet NaN, 0x7F80_0000 +Inf.
    assert_eq!(
        decode_field(&f32f, 0, &[0x7FC0, 0]).map(|r| r.status),
        Ok(ReadingStatus::NotFinite)
    );
    assert_eq!(
        decode_field(&f32f, 0, &[0x7F80, 0]).map(|r| r.status),
        Ok(ReadingStatus::NotFinite)
    );
    // A huge but finite f32 scaled into overflow is also not finite.
    let mut big = f32f.clone();
    big.scale = 1e300;
    assert_eq!(
        decode_field(&big, 0, &encode_raw(3.0e38, DataType::F32, ByteOrder::ABCD))
            .map(|r| r.status),
        Ok(ReadingStatus::NotFinite)
    );
}

fn good_map() -> ModbusConfig {
    let sig = |name: &str, address: u32, s: Signal| FieldSpec {
        signal: Some(s),
        ..field(name, address, DataType::F32)
    };
    ModbusConfig {
        endpoint: "127.0.0.1:502".into(),
        requests: vec![RequestSpec {
            slave_id: 1,
            register: RegisterKind::Holding,
            start_address: 0,
            count: None,
            fields: vec![
                sig("n1_rpm", 0, Signal::N1),
                sig("t2_k", 2, Signal::T2),
                sig("p2_kpa", 4, Signal::P2),
                sig("t34_k", 6, Signal::T34),
                sig("p34_kpa", 8, Signal::P34),
                sig("fuel_kg_s", 10, Signal::FuelFlow),
            ],
        }],
    }
}

fn keys(p: &[ConfigProblem]) -> Vec<String> {
    p.iter().map(|p| p.key.clone()).collect()
}

#[test]
fn good_map_has_no_problems() {
    let m = good_map();
    assert_eq!(m.check(), vec![]);
    assert_eq!(m.requests[0].register_count(), 12);
}

#[test]
fn every_problem_is_reported_not_just_the_first() {
    let mut m = good_map();
    m.endpoint = "plc".into();
    let r = &mut m.requests[0];
    r.slave_id = 0;
    r.fields[1].address = 1; // overlaps n1 (0–1)
    r.fields[2].scale = 0.0;
    r.fields[3].min = Some(5.0);
    r.fields[3].max = Some(1.0);
    r.fields.pop(); // drop fuel flow
    r.fields.push(field("spare", 200, DataType::U16)); // spans 0–200 → 201 registers
    let p = m.check();
    assert_eq!(
        keys(&p),
        vec![
            "modbus.endpoint",
            "modbus.request[0].slave_id",
            "modbus.request[0].count",
            "modbus.request[0].field[1].address",
            "modbus.request[0].field[2].scale",
            "modbus.request[0].field[3].max",
            "modbus.request",
        ],
        "{p:#?}"
    );
    assert_eq!(
        p[3].message,
        "registers 1–2 (f32 holding, slave 0) overlap field 'n1_rpm' (modbus.request[0].field[0])"
    );
    assert_eq!(
        p[2].message,
        "request spans 201 registers (0–200); one Modbus read may ask for at most 125: \
         split it into several requests"
    );
    assert_eq!(
        p[6].message,
        "missing required tags for diagnosis: fuel_flow (add a field with signal = \"…\" for each)"
    );
}

#[test]
fn modicon_addresses_get_a_specific_hint() {
    let mut m = good_map();
    m.requests[0].start_address = 40001;
    for (i, f) in m.requests[0].fields.iter_mut().enumerate() {
        f.address = 40001 + 2 * i as u32;
    }
    let p = m.check();
    assert_eq!(p[0].key, "modbus.request[0].start_address");
    assert_eq!(
        p[0].message,
        "40001 looks like the 1-based Modicon notation for holding register 1 (4xxxx); \
         addresses here are 0-based, so write 0"
    );
    assert_eq!(p[1].key, "modbus.request[0].field[0].address");
    // 3xxxx on a holding request also says the table looks wrong.
    assert_eq!(
        modicon_hint(30011, RegisterKind::Holding).as_deref(),
        Some(
            "30011 looks like the 1-based Modicon notation for input register 11 (3xxxx); \
             addresses here are 0-based, so write 10 and check register = \"input\" \
             (this request reads holding registers)"
        )
    );
    assert_eq!(
        modicon_hint(400101, RegisterKind::Holding).as_deref(),
        Some(
            "400101 looks like the 1-based Modicon notation for holding register 101 (4xxxx); \
             addresses here are 0-based, so write 100"
        )
    );
    assert_eq!(modicon_hint(29999, RegisterKind::Holding), None);
    assert_eq!(modicon_hint(40000, RegisterKind::Holding), None);
}

#[test]
fn type_wider_than_the_registers_of_the_request() {
    let mut m = good_map();
    m.requests[0].count = Some(11); // fuel flow f32 at 10 needs 10–11
    let p = m.check();
    assert_eq!(keys(&p), vec!["modbus.request[0].field[5].type"]);
    assert_eq!(
        p[0].message,
        "f32 needs 2 registers (10–11) but the request reads only 0–10 (count = 11): \
         the type is wider than the registers left"
    );
}

#[test]
fn overlap_across_requests_of_same_slave_and_table_only() {
    let mut m = good_map();
    let mut second = RequestSpec {
        slave_id: 1,
        register: RegisterKind::Holding,
        start_address: 4,
        count: None,
        fields: vec![field("extra", 5, DataType::U16)],
    };
    m.requests.push(second.clone());
    let p = m.check();
    assert_eq!(keys(&p), vec!["modbus.request[1].field[0].address"]);
    assert!(
        p[0].message.contains("overlap field 'p2_kpa'"),
        "{}",
        p[0].message
    );
    // Input registers are a different table: no overlap.
    second.register = RegisterKind::Input;
    m.requests[1] = second.clone();
    assert_eq!(m.check(), vec![]);
    // Another slave: no overlap either.
    second.register = RegisterKind::Holding;
    second.slave_id = 2;
    m.requests[1] = second;
    assert_eq!(m.check(), vec![]);
}

#[test]
fn duplicate_names_and_signals() {
    let mut m = good_map();
    let mut dup = m.requests[0].fields[0].clone();
    dup.address = 20;
    m.requests[0].fields.push(dup);
    let p = m.check();
    assert_eq!(
        p,
        vec![
            ConfigProblem::new(
                "modbus.request[0].field[6].name",
                "tag name 'n1_rpm' is already used by modbus.request[0].field[0]"
            ),
            ConfigProblem::new(
                "modbus.request[0].field[6].signal",
                "signal n1 is already fed by modbus.request[0].field[0]"
            ),
        ]
    );
}

#[test]
fn toml_round_trip_and_signal_names() {
    let text = r#"
endpoint = "10.0.0.5:502"
[[request]]
slave_id = 1
register = "input"
start_address = 0
[[request.field]]
name = "t2_k"
address = 0
type = "u16"
byte_order = "BADC"
scale = 0.1
signal = "T2"
"#;
    let m: ModbusConfig = toml::from_str(text).expect("parse");
    assert_eq!(m.requests[0].fields[0].signal, Some(Signal::T2));
    assert_eq!(m.requests[0].fields[0].byte_order, ByteOrder::BADC);
    let bad = text.replace("\"T2\"", "\"T9\"");
    let e = toml::from_str::<ModbusConfig>(&bad).expect_err("bad signal");
    assert!(e.to_string().contains("unknown signal 'T9'"), "{e}");
    let bad = text.replace("scale = 0.1", "scale = 0.1\nbyteorder = \"ABCD\"");
    let e = toml::from_str::<ModbusConfig>(&bad).expect_err("unknown key");
    assert!(e.to_string().contains("unknown field `byteorder`"), "{e}");
}
