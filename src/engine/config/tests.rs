//! Tests of engine-file parsing and validation.

use super::*;

#[test]
fn reference_engine_parses() {
    let cfg = EngineConfig::reference();
    assert_eq!(cfg.design.pressure_ratio, 24.1);
    assert_eq!(cfg.dynamics.gg_inertia_kg_m2, 40.0);
}

#[test]
fn unknown_key_is_named() {
    let text = REFERENCE_ENGINE_TOML.replace("[ambient]", "[ambient]\nhumidity_pct = 3");
    let err = EngineConfig::from_toml_str(&text, "x.toml").expect_err("unknown key");
    assert!(err.to_string().contains("humidity_pct"), "{err}");
}

#[test]
fn invalid_value_is_named() {
    let text = REFERENCE_ENGINE_TOML.replace(
        "compressor_efficiency = 0.85",
        "compressor_efficiency = 1.5",
    );
    let err = EngineConfig::from_toml_str(&text, "x.toml").expect_err("bad value");
    assert!(
        err.to_string().contains("design.compressor_efficiency"),
        "{err}"
    );
}

/// Map paths in `[maps]` are relative to the engine file, not the working directory; a
/// missing map is named once, with its key.
#[test]
fn map_paths_resolve_against_the_engine_file() {
    let dir = tempfile::tempdir().expect("tempdir");
    let sub = dir.path().join("maps_here");
    std::fs::create_dir(&sub).expect("mkdir");
    std::fs::write(sub.join("hpc.map"), crate::maps::HPC_MAP).expect("write map");
    let text = REFERENCE_ENGINE_TOML.replace(
        "compressor_file = \"\"",
        "compressor_file = \"maps_here/hpc.map\"",
    );
    let file = dir.path().join("engine.toml");
    std::fs::write(&file, &text).expect("write engine");
    // The test runs in the crate root, where `maps_here/hpc.map` does not exist.
    assert!(!Path::new("maps_here/hpc.map").exists());
    let cfg = EngineConfig::load(&file).expect("loads");
    assert_eq!(
        Path::new(&cfg.maps.compressor_file),
        sub.join("hpc.map").as_path()
    );
    // Same map as the embedded one: the same calibrated engine.
    let e = crate::engine::Engine::new(cfg).expect("engine");
    let r = crate::engine::Engine::reference().expect("reference");
    assert_eq!(e.design(), r.design());
    // Absolute paths are kept as they are.
    let abs = sub.join("hpc.map").display().to_string();
    let text = REFERENCE_ENGINE_TOML.replace(
        "compressor_file = \"\"",
        &format!("compressor_file = {abs:?}"),
    );
    let other = tempfile::tempdir().expect("tempdir");
    let file2 = other.path().join("engine.toml");
    std::fs::write(&file2, text).expect("write engine");
    let cfg = EngineConfig::load(&file2).expect("loads");
    assert_eq!(cfg.maps.compressor_file, abs);
    // A missing map: one mention of the file, and the key.
    let text = REFERENCE_ENGINE_TOML.replace("hpt_file = \"\"", "hpt_file = \"nope.map\"");
    std::fs::write(&file, text).expect("write engine");
    let cfg = EngineConfig::load(&file).expect("loads");
    let err = crate::engine::Engine::new(cfg)
        .expect_err("missing map")
        .to_string();
    assert_eq!(err.matches("nope.map").count(), 1, "{err}");
    assert!(
        err.contains("maps.hpt_file") && err.contains("cannot read map file"),
        "{err}"
    );
    // Not chained as a source either, so an error-chain printer cannot repeat it.
    let e = crate::engine::Engine::new(EngineConfig::load(&file).expect("loads"))
        .expect_err("missing map");
    assert!(std::error::Error::source(&e).is_none());
}

/// A map named by path is written into the file as its text: the engine built from the
/// self-contained text is the one built from the file and its map, wherever it is read; a map
/// given both ways is refused with the key named; a file without map paths is returned as it
/// was; a map file that cannot be read is named with its key.
#[test]
fn map_files_are_written_into_a_self_contained_engine_text() {
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::write(dir.path().join("c.map"), crate::maps::HPC_MAP).expect("write map");
    std::fs::write(dir.path().join("t.map"), crate::maps::HPT_MAP).expect("write map");
    let text = REFERENCE_ENGINE_TOML
        .replace("compressor_file = \"\"", "compressor_file = \"c.map\"")
        .replace("hpt_file = \"\"", "hpt_file = \"t.map\"");
    let inlined = inline_map_files(&text, Some(dir.path())).expect("inlines");
    assert!(
        !inlined.contains("c.map") && !inlined.contains("t.map"),
        "{inlined}"
    );
    let cfg = EngineConfig::from_toml_str(&inlined, "inlined").expect("parses");
    assert_eq!(cfg.maps.compressor_file, "");
    assert_eq!(cfg.maps.compressor_map, crate::maps::HPC_MAP);
    assert_eq!(cfg.maps.hpt_map, crate::maps::HPT_MAP);
    assert_eq!(cfg.maps.pt_map, "", "the embedded PT map stays embedded");
    let from_text = crate::engine::Engine::new(cfg).expect("engine");
    let r = crate::engine::Engine::reference().expect("reference");
    assert_eq!(from_text.design(), r.design());
    // The reference engine names no file: its text is unchanged.
    assert_eq!(
        inline_map_files(REFERENCE_ENGINE_TOML, None).expect("nothing to do"),
        REFERENCE_ENGINE_TOML
    );
    // Both ways at once: refused, the key named.
    let both = inlined.replace("compressor_file = \"\"", "compressor_file = \"c.map\"");
    let err = EngineConfig::from_toml_str(&both, "both.toml")
        .expect_err("twice")
        .to_string();
    assert!(
        err.contains("maps.compressor_map") && err.contains("twice"),
        "{err}"
    );
    // A map file that is not there.
    let err = inline_map_files(&text, Some(&dir.path().join("elsewhere")))
        .expect_err("missing")
        .to_string();
    assert!(
        err.contains("maps.compressor_file") && err.contains("c.map"),
        "{err}"
    );
    // An inline map that does not parse is reported under its key.
    let mut cfg = EngineConfig::from_toml_str(&inlined, "inlined").expect("parses");
    cfg.maps.compressor_map = "not a map".into();
    let err = crate::engine::Engine::new(cfg)
        .expect_err("bad map")
        .to_string();
    assert!(err.contains("maps.compressor_map"), "{err}");
}

/// Efficiencies are in (0, 1]: exactly 1 is accepted (ideal combustion, lossless shafts),
/// 0, above 1 and non-finite values are refused with the key named.
#[test]
fn efficiencies_accept_one_and_refuse_zero_and_nan() {
    let keys = [
        (
            "compressor_efficiency = 0.85",
            "design.compressor_efficiency",
        ),
        (
            "combustion_efficiency = 0.995",
            "design.combustion_efficiency",
        ),
        (
            "gg_mechanical_efficiency = 0.99",
            "design.gg_mechanical_efficiency",
        ),
        (
            "pt_mechanical_efficiency = 0.99",
            "design.pt_mechanical_efficiency",
        ),
        ("hpt_efficiency = 0.88", "design.hpt_efficiency"),
    ];
    for (from, key) in keys {
        assert!(REFERENCE_ENGINE_TOML.contains(from), "{from}");
        let name = from.split(' ').next().unwrap_or(from);
        let ok = REFERENCE_ENGINE_TOML.replace(from, &format!("{name} = 1.0"));
        let cfg = EngineConfig::from_toml_str(&ok, "x.toml").expect(key);
        let leaf = key.split('.').nth(1).unwrap_or(key);
        let v = serde_json::to_value(&cfg.design).expect("json")[leaf].as_f64();
        assert_eq!(v, Some(1.0), "{key}");
        for bad in ["0.0", "1.0001", "nan", "inf", "-0.5"] {
            let text = REFERENCE_ENGINE_TOML.replace(from, &format!("{name} = {bad}"));
            let err = EngineConfig::from_toml_str(&text, "x.toml").expect_err(bad);
            assert!(err.to_string().contains(key), "{key} = {bad}: {err}");
        }
    }
    // Ideal combustion and lossless shafts calibrate.
    let text = REFERENCE_ENGINE_TOML
        .replace(
            "combustion_efficiency = 0.995",
            "combustion_efficiency = 1.0",
        )
        .replace(
            "gg_mechanical_efficiency = 0.99",
            "gg_mechanical_efficiency = 1.0",
        )
        .replace(
            "pt_mechanical_efficiency = 0.99",
            "pt_mechanical_efficiency = 1.0",
        );
    let cfg = EngineConfig::from_toml_str(&text, "x.toml").expect("ideal");
    crate::engine::Engine::new(cfg).expect("calibrates");
}

/// The legacy `mechanical_efficiency` sets both shafts; with a per-shaft key it is an error.
#[test]
fn legacy_mechanical_efficiency_sets_both_shafts() {
    let per_shaft = "gg_mechanical_efficiency = 0.99  # gas-generator shaft: HPT gas power x this drives the compressor\npt_mechanical_efficiency = 0.99";
    let text = REFERENCE_ENGINE_TOML.replace(per_shaft, "mechanical_efficiency = 0.97");
    assert_ne!(text, REFERENCE_ENGINE_TOML);
    let cfg = EngineConfig::from_toml_str(&text, "x.toml").expect("legacy");
    assert_eq!(cfg.design.gg_mechanical_efficiency, 0.97);
    assert_eq!(cfg.design.pt_mechanical_efficiency, 0.97);
    let text = REFERENCE_ENGINE_TOML.replace(
        "pt_mechanical_efficiency = 0.99",
        "mechanical_efficiency = 0.97",
    );
    let err = EngineConfig::from_toml_str(&text, "x.toml").expect_err("both");
    assert!(
        err.to_string().contains("design.mechanical_efficiency"),
        "{err}"
    );
    // The legacy key still gets a bad value named.
    let text = REFERENCE_ENGINE_TOML.replace(per_shaft, "mechanical_efficiency = nan");
    let err = EngineConfig::from_toml_str(&text, "x.toml").expect_err("nan");
    assert!(err.to_string().contains("mechanical_efficiency"), "{err}");
}

/// The `[fuel]` section: a gas by composition or a liquid by H/C; bad descriptions name their
/// key; it and `design.fuel_lhv_j_per_kg` exclude each other; with neither, methane.
#[test]
fn fuel_section_is_read_and_checked() {
    let lhv_line = "fuel_lhv_j_per_kg = 50.0e6    # methane, fuel delivered at 288.15 K\n";
    assert!(REFERENCE_ENGINE_TOML.contains(lhv_line));
    let without_lhv = REFERENCE_ENGINE_TOML.replace(lhv_line, "");
    let with = |section: &str| format!("{without_lhv}\n{section}\n");
    let gas = "[fuel]\nkind = \"gas\"\ntemperature_k = 300.0\n[fuel.composition]\nCH4 = 0.9\nC2H6 = 0.05\nN2 = 0.05";
    let cfg = EngineConfig::from_toml_str(&with(gas), "x.toml").expect("gas fuel");
    let fuel = cfg.fuel().expect("fuel");
    // 0.9 CH4 + 0.05 C2H6 + 0.05 N2: (0.9·802.69 + 0.05·1428.84) kJ/mol (ISO 6976) over
    // 17.342 kg/kmol = 45.78 MJ/kg.
    assert!((fuel.lhv() / 45.78e6 - 1.0).abs() < 1e-3, "{}", fuel.lhv());
    assert!(fuel.sensible_enthalpy() > 0.0);
    crate::engine::Engine::new(cfg).expect("calibrates on the gas");
    let liquid = "[fuel]\nkind = \"liquid\"\ntemperature_k = 300.0\nh_to_c_ratio = 1.92";
    let cfg = EngineConfig::from_toml_str(&with(liquid), "x.toml").expect("liquid fuel");
    let e = crate::engine::Engine::new(cfg).expect("calibrates on the liquid");
    assert!((e.consts().fuel.lhv() / 43.2e6 - 1.0).abs() < 0.01);
    // Neither: methane by composition at 288.15 K.
    let cfg = EngineConfig::from_toml_str(&without_lhv, "x.toml").expect("default");
    assert!((cfg.fuel().expect("methane").lhv() / 50.03e6 - 1.0).abs() < 1e-3);
    // Errors name the key.
    for (text, key) in [
        (
            with(&gas.replace("N2 = 0.05", "N2 = 0.08")),
            "fuel.composition",
        ),
        (with(&gas.replace("N2 = 0.05", "C5H12 = 0.05")), "C5H12"),
        (
            with(&gas.replace("N2 = 0.05", "N2 = -0.05")),
            "fuel.composition.N2",
        ),
        (with(&gas.replace("300.0", "1300.0")), "fuel.temperature_k"),
        (
            with(&liquid.replace("h_to_c_ratio = 1.92", "")),
            "fuel.h_to_c_ratio",
        ),
        (
            with(&format!("{liquid}\n[fuel.composition]\nCH4 = 1.0")),
            "fuel.composition",
        ),
        (
            format!("{REFERENCE_ENGINE_TOML}\n{gas}\n"),
            "design.fuel_lhv_j_per_kg",
        ),
    ] {
        let err = EngineConfig::from_toml_str(&text, "x.toml").expect_err(key);
        assert!(err.to_string().contains(key), "{key}: {err}");
    }
}

/// No `[fuel]` section: the legacy methane, whose products and heat are exactly those of
/// before (`Gas::products`, `wf·η_b·LHV`), so every result is bit for bit unchanged.
#[test]
fn legacy_fuel_is_bit_for_bit_methane() {
    let e = crate::engine::Engine::reference().expect("reference");
    let c = e.consts();
    assert_eq!(c.fuel.lhv(), 50.0e6);
    assert_eq!(c.fuel.sensible_enthalpy(), 0.0);
    for i in 0..200 {
        let wf = i as f64 * 0.0173;
        assert_eq!(
            c.fuel_heat_w(wf).to_bits(),
            (wf * c.eta_b * 50.0e6).to_bits()
        );
        let far = i as f64 * 3.7e-4;
        assert_eq!(c.fuel.products(far), crate::thermo::Gas::products(far));
    }
}

/// `nozzle` is an exhaust law: accepted there (the file reads it), refused on the inlet and
/// the combustor with the key named.
#[test]
fn the_nozzle_law_is_for_the_exhaust_only() {
    for key in ["inlet_loss_law", "combustor_loss_law", "exhaust_loss_law"] {
        let from = format!("{key} = \"flow_squared\"");
        assert!(REFERENCE_ENGINE_TOML.contains(&from), "{from}");
        let text = REFERENCE_ENGINE_TOML.replacen(&from, &format!("{key} = \"nozzle\""), 1);
        let read = EngineConfig::from_toml_str(&text, "x.toml");
        if key == "exhaust_loss_law" {
            let cfg = read.expect("exhaust nozzle");
            assert_eq!(cfg.design.exhaust_loss_law, PressureLossLaw::Nozzle);
        } else {
            let err = read.expect_err(key).to_string();
            assert!(
                err.contains(&format!("design.{key}")) && err.contains("exhaust law only"),
                "{err}"
            );
        }
    }
}
