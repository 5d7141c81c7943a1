//! The options schema (`options.rs` and the `OPTIONS` tables beside the configuration structs):
//! every default passes its own validation and is what the structs' defaults hold; a value out
//! of range is refused with the option's name and range; a configuration survives the round
//! trip through its key → value map.

use granrs_core::grid::{BoundaryConditions, Grid, VelocityBc};
use granrs_core::models::{Material, ModelConfig};
use granrs_core::options::{Kind, OptionMap, OptionSpec, Value};
use granrs_core::pore_pressure::{PorePressureConfig, PORE_PRESSURE_OPTIONS};
use granrs_core::rheology::RheologyLaw;

fn base() -> ModelConfig {
    let grid = Grid::new(16, 8, 2.0, 1.0).unwrap();
    let mut cfg = ModelConfig::single_phase(grid, BoundaryConditions::uniform(VelocityBc::FreeSlip), Material { density: 1000.0, viscosity: 1e-3 });
    cfg.light = Some(Material { density: 1.0, viscosity: 2e-5 });
    cfg
}

fn all_specs() -> Vec<&'static OptionSpec> {
    let mut v = ModelConfig::schema();
    v.extend(ModelConfig::object_schema());
    v
}

#[test]
fn every_default_passes_its_own_validation() {
    for s in all_specs() {
        if s.default == Value::None && !s.optional {
            continue; // a required parameter: no default to check
        }
        assert_eq!(s.check(&s.default).as_ref(), Ok(&s.default), "default of `{}`", s.key);
        if let Kind::Choice(names) = s.kind {
            assert!(names.contains(&granrs_core::options::as_name(&s.default)), "{}", s.key);
        }
    }
}

#[test]
fn flat_keys_are_unique() {
    let schema = ModelConfig::schema();
    for (k, s) in schema.iter().enumerate() {
        assert!(schema[k + 1..].iter().all(|t| t.key != s.key), "key `{}` twice", s.key);
    }
}

#[test]
fn struct_defaults_are_the_schema_defaults() {
    let cfg = base();
    let map = cfg.to_options();
    for s in ModelConfig::schema() {
        assert_eq!(map.get(s.key), Some(&s.default), "`{}`", s.key);
    }
    cfg.validate().unwrap();
}

/// A value just outside the range of a numeric option (None where the range is unbounded).
fn outside(s: &OptionSpec) -> Option<Value> {
    match s.kind {
        Kind::Float { hi, hi_open, lo, lo_open } => {
            if hi.is_finite() {
                Some(Value::Float(if hi_open { hi } else { hi * 1.5 + 1.0 }))
            } else if lo.is_finite() {
                Some(Value::Float(if lo_open { lo } else { lo - 1.0 - lo.abs() }))
            } else {
                Some(Value::Float(f64::NAN))
            }
        }
        Kind::Int { hi, .. } => Some(Value::Int(hi + 1)),
        Kind::Bool => Some(Value::Int(1)),
        Kind::Choice(_) => Some(Value::str("no-such-choice")),
    }
}

#[test]
fn out_of_range_is_refused_with_name_and_range() {
    for s in ModelConfig::schema() {
        let bad = outside(s).unwrap();
        let mut map = OptionMap::new();
        map.insert(s.key.to_string(), bad.clone());
        let err = ModelConfig::from_options(base().grid.clone(), base().bc, base().dense, &map).expect_err(s.key).to_string();
        assert!(err.contains(&format!("`{}`", s.key)) && err.contains(&s.allowed()), "{}: {err}", s.key);
    }
    let mut map = OptionMap::new();
    map.insert("no_such_option".into(), Value::Int(1));
    let err = ModelConfig::from_options(base().grid.clone(), base().bc, base().dense, &map).unwrap_err().to_string();
    assert!(err.contains("no_such_option") && err.contains("theta"), "{err}");
}

/// A valid value of `s` other than its default.
fn another(s: &OptionSpec) -> Value {
    match s.kind {
        Kind::Float { lo, hi, .. } => {
            let d = s.default.as_f64().unwrap_or(if lo.is_finite() { lo + 1.0 } else { 1.0 });
            let x = if d.is_finite() && d * 1.01 < hi { d * 1.01 + 1e-12 } else { 0.5 * (lo.max(0.0) + hi.min(1e6)) };
            Value::Float(x)
        }
        Kind::Int { lo, hi } => {
            let d = match s.default {
                Value::Int(i) => i,
                _ => lo,
            };
            Value::Int(if d < hi { d + 1 } else { lo })
        }
        Kind::Bool => Value::Bool(s.default != Value::Bool(true)),
        Kind::Choice(names) => Value::str(names.iter().find(|n| Value::str(n) != s.default).unwrap()),
    }
}

#[test]
fn round_trip_through_the_map() {
    let cfg = base();
    let again = ModelConfig::from_options(cfg.grid.clone(), cfg.bc, cfg.dense, &cfg.to_options()).unwrap();
    assert_eq!(again.to_options(), cfg.to_options());
    // every option away from its default at once (less the pairs that exclude each other)
    for s in ModelConfig::schema() {
        let mut map = OptionMap::new();
        let v = another(s);
        map.insert(s.key.to_string(), v.clone());
        if s.key.starts_with("active_region_") {
            map.insert("active_region".into(), Value::Int(16)); // align and sides belong to a region
        }
        if s.key == "plastic" {
            map.insert("regularisation".into(), Value::Float(10.0));
        }
        let got = ModelConfig::from_options(cfg.grid.clone(), cfg.bc, cfg.dense, &map).unwrap_or_else(|e| panic!("{}: {e}", s.key));
        let out = got.to_options();
        let want = s.check(&v).unwrap();
        let expected = if s.key == "regularisation" { Value::None } else { want };
        assert_eq!(out.get(s.key), Some(&expected), "`{}`", s.key);
        assert_eq!(ModelConfig::from_options(cfg.grid.clone(), cfg.bc, cfg.dense, &out).unwrap().to_options(), out, "`{}`", s.key);
    }
}

#[test]
fn pore_pressure_and_law_round_trip() {
    let mut map = OptionMap::new();
    map.insert("diffusivity".into(), Value::Float(0.035));
    map.insert("basal_gradient".into(), Value::Float(-12800.0));
    map.insert("basal_x_min".into(), Value::Float(0.0));
    map.insert("basal_x_max".into(), Value::Float(0.2));
    map.insert("formulation".into(), Value::str("kappa-infinity"));
    map.insert("kappa_air".into(), Value::Float(1e8));
    let pore = PorePressureConfig::from_options(&map).unwrap();
    assert_eq!(PorePressureConfig::from_options(&pore.to_options()).unwrap(), pore);
    for (k, v) in &map {
        assert_eq!(pore.to_options().get(k), Some(v), "{k}");
    }
    let err = PorePressureConfig::from_options(&OptionMap::new()).unwrap_err().to_string();
    assert!(err.contains("pore_pressure.diffusivity"), "{err}");
    assert!(PORE_PRESSURE_OPTIONS.iter().any(|s| s.key == "kappa_air"));

    let dp = RheologyLaw::from_options("drucker-prager", &OptionMap::new()).unwrap();
    assert_eq!(dp, RheologyLaw::DruckerPrager { friction_angle: 27.0 });
    assert_eq!(RheologyLaw::from_options("drucker-prager", &dp.to_options()).unwrap(), dp);
    let mut bad = OptionMap::new();
    bad.insert("friction_angle".into(), Value::Float(90.0));
    let err = RheologyLaw::from_options("drucker-prager", &bad).unwrap_err().to_string();
    assert!(err.contains("`friction_angle`") && err.contains("(0, 90)"), "{err}");
    let err = RheologyLaw::from_options("bingham", &OptionMap::new()).unwrap_err().to_string();
    assert!(err.contains("yield_stress") && err.contains("required"), "{err}");
}
