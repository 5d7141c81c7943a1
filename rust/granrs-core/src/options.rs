//! The options schema: how an option of granrs is declared, validated and read from or written to
//! a key → value map.
//!
//! Each option is declared once, as an [`OptionSpec`] in the `OPTIONS` table beside the field of
//! the configuration struct of the room that uses it (`ModelConfig` in `models/two_phase.rs`,
//! `TimeConfig` in `time_stepping/clock.rs`, `SolverSettings` in `solvers/mod.rs`,
//! `RedistanceSettings` in `levelset/redistance.rs`, `RheologyConfig` and the laws in
//! `rheology/mod.rs`, `PorePressureConfig` in `pore_pressure/mod.rs`, `ActiveRegion` in
//! `models/active_region.rs`). A spec holds the option's key, its room, its kind and range, its
//! default, its unit, one line of doc and its group: [`Group::Common`] for what a user sets,
//! [`Group::Variant`] for a numerical variant kept for study (docs/models.md, "Variants").
//!
//! The struct's `Default` reads its defaults from the table ([`OptionSpec::float`] and friends),
//! its `validate` checks each field against the table ([`OptionSpec::check`]), and
//! [`Configurable`] maps the fields to keys, so that [`apply`] and [`to_map`] read and write a
//! whole room from a map. The Python binding exports the tables (`granrs._granrs.schema()`);
//! the Python classes, run-file keys, `granrs keys` and the docs' key reference derive from it.

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::fmt;

use crate::error::{Error, Result};

/// Whether an option is one a user sets, or a numerical variant kept for study.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Group {
    /// An option of the common case.
    Common,
    /// A numerical variant or a reading of the paper kept for study; the default is the
    /// measured choice (docs/models.md, "Variants").
    Variant,
}

impl Group {
    /// Name used in Python and the docs.
    pub fn name(&self) -> &'static str {
        match self {
            Group::Common => "common",
            Group::Variant => "variant",
        }
    }
}

/// The kind of value an option takes, with its allowed range.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Kind {
    /// A real number in the interval from `lo` to `hi` (each end included unless open; an
    /// infinite end that is included admits ±∞ itself).
    Float { lo: f64, hi: f64, lo_open: bool, hi_open: bool },
    /// An integer in [lo, hi].
    Int { lo: i64, hi: i64 },
    /// true or false.
    Bool,
    /// One of the names.
    Choice(&'static [&'static str]),
}

/// A value of an option.
#[derive(Clone, Debug, PartialEq)]
pub enum Value {
    Float(f64),
    Int(i64),
    Bool(bool),
    Str(Cow<'static, str>),
    /// No value: the option is off, or derived (see its doc).
    None,
}

impl Value {
    /// A string value.
    pub fn str(s: &str) -> Value {
        Value::Str(Cow::Owned(s.to_string()))
    }

    /// The value as a float (an integer converts); None otherwise.
    pub fn as_f64(&self) -> Option<f64> {
        match self {
            Value::Float(x) => Some(*x),
            Value::Int(i) => Some(*i as f64),
            _ => None,
        }
    }

    /// `Some(x)` of an optional float.
    pub fn opt_f64(x: Option<f64>) -> Value {
        x.map(Value::Float).unwrap_or(Value::None)
    }
}

impl fmt::Display for Value {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Value::Float(x) => write!(f, "{x}"),
            Value::Int(i) => write!(f, "{i}"),
            Value::Bool(b) => write!(f, "{b}"),
            Value::Str(s) => write!(f, "'{s}'"),
            Value::None => write!(f, "None"),
        }
    }
}

/// The declaration of one option.
#[derive(Clone, Debug, PartialEq)]
pub struct OptionSpec {
    /// The option's key (unique within its room; the keys of the model's flat options are
    /// unique over all their rooms).
    pub key: &'static str,
    /// The room (the object of the Python package and the run-file section that holds it):
    /// "model", "time", "pressure_solver", "interface", "bi_projection", "active_region",
    /// "pore_pressure", "coulomb", "side_walls", or a rheology law.
    pub room: &'static str,
    pub kind: Kind,
    /// The default ([`Value::None`]: off, or derived; see `doc`).
    pub default: Value,
    /// Whether [`Value::None`] is allowed (an option that can be off).
    pub optional: bool,
    /// Unit: SI symbols ("m", "s", "Pa s", "m2 s-1", "degree"), "1" dimensionless, "" none.
    pub unit: &'static str,
    /// One line of doc.
    pub doc: &'static str,
    pub group: Group,
}

/// A float option in [lo, hi].
pub const fn float(room: &'static str, key: &'static str, default: f64, lo: f64, hi: f64, unit: &'static str, doc: &'static str) -> OptionSpec {
    OptionSpec {
        key,
        room,
        kind: Kind::Float { lo, hi, lo_open: false, hi_open: false },
        default: Value::Float(default),
        optional: false,
        unit,
        doc,
        group: Group::Common,
    }
}

/// An integer option in [lo, hi].
pub const fn int(room: &'static str, key: &'static str, default: i64, lo: i64, hi: i64, unit: &'static str, doc: &'static str) -> OptionSpec {
    OptionSpec { key, room, kind: Kind::Int { lo, hi }, default: Value::Int(default), optional: false, unit, doc, group: Group::Common }
}

/// A boolean option.
pub const fn boolean(room: &'static str, key: &'static str, default: bool, doc: &'static str) -> OptionSpec {
    OptionSpec { key, room, kind: Kind::Bool, default: Value::Bool(default), optional: false, unit: "", doc, group: Group::Common }
}

/// A choice among names (the default is one of them).
pub const fn choice(room: &'static str, key: &'static str, default: &'static str, names: &'static [&'static str], doc: &'static str) -> OptionSpec {
    OptionSpec { key, room, kind: Kind::Choice(names), default: Value::Str(Cow::Borrowed(default)), optional: false, unit: "", doc, group: Group::Common }
}

impl OptionSpec {
    /// The same option in the group of variants.
    pub const fn variant(mut self) -> Self {
        self.group = Group::Variant;
        self
    }

    /// The same option, admitting None (off), with None as its default.
    pub const fn off_by_default(mut self) -> Self {
        self.optional = true;
        std::mem::forget(std::mem::replace(&mut self.default, Value::None));
        self
    }

    /// The same option with the ends of its float range open as given.
    pub const fn open(mut self, lo_open: bool, hi_open: bool) -> Self {
        if let Kind::Float { lo, hi, .. } = self.kind {
            self.kind = Kind::Float { lo, hi, lo_open, hi_open };
        }
        self
    }

    /// The same option with no default: a value is required.
    pub const fn required(mut self) -> Self {
        std::mem::forget(std::mem::replace(&mut self.default, Value::None));
        self.optional = false;
        self
    }

    /// The allowed values, in words (the error messages, `granrs keys` and the docs use it).
    pub fn allowed(&self) -> String {
        let unit = match self.unit {
            "" => String::new(),
            "1" => " (dimensionless)".to_string(),
            u => format!(" ({u})"),
        };
        let what = match self.kind {
            Kind::Float { lo, hi, lo_open, hi_open } => {
                format!("a number in {}{}, {}{}{unit}", if lo_open { "(" } else { "[" }, fmt_num(lo), fmt_num(hi), if hi_open { ")" } else { "]" })
            }
            Kind::Int { lo, hi } => format!("an integer in [{lo}, {hi}]{unit}"),
            Kind::Bool => "true or false".to_string(),
            Kind::Choice(names) => {
                let q: Vec<String> = names.iter().map(|n| format!("'{n}'")).collect();
                format!("one of {}", q.join(", "))
            }
        };
        if self.optional {
            format!("None or {what}")
        } else {
            what
        }
    }

    /// The value converted to the option's kind (an integer for a float option becomes a
    /// float), or an error naming the option and its allowed values.
    pub fn check(&self, value: &Value) -> Result<Value> {
        self.check_named(self.key, value)
    }

    /// [`OptionSpec::check`] with the error naming `name` (a struct used in several places
    /// names its own field).
    pub fn check_named(&self, name: &str, value: &Value) -> Result<Value> {
        let bad = || Error::param(name, value, &self.allowed());
        if *value == Value::None {
            return if self.optional { Ok(Value::None) } else { Err(bad()) };
        }
        match self.kind {
            Kind::Float { lo, hi, lo_open, hi_open } => {
                let x = value.as_f64().filter(|_| !matches!(value, Value::Bool(_))).ok_or_else(bad)?;
                let above = if lo_open { x > lo } else { x >= lo };
                let below = if hi_open { x < hi } else { x <= hi };
                if x.is_nan() || !above || !below {
                    return Err(bad());
                }
                Ok(Value::Float(x))
            }
            Kind::Int { lo, hi } => match value {
                Value::Int(i) if (lo..=hi).contains(i) => Ok(Value::Int(*i)),
                _ => Err(bad()),
            },
            Kind::Bool => match value {
                Value::Bool(_) => Ok(value.clone()),
                _ => Err(bad()),
            },
            Kind::Choice(names) => match value {
                Value::Str(s) if names.contains(&s.as_ref()) => Ok(value.clone()),
                _ => Err(bad()),
            },
        }
    }

    /// Checks a float field.
    pub fn check_f64(&self, x: f64) -> Result<()> {
        self.check(&Value::Float(x)).map(|_| ())
    }

    /// Checks an optional float field.
    pub fn check_opt_f64(&self, x: Option<f64>) -> Result<()> {
        self.check(&Value::opt_f64(x)).map(|_| ())
    }

    /// Checks an integer field.
    pub fn check_usize(&self, n: usize) -> Result<()> {
        self.check(&Value::Int(i64::try_from(n).unwrap_or(i64::MAX))).map(|_| ())
    }

    /// The default of a float option.
    pub fn float(&self) -> f64 {
        match self.default {
            Value::Float(x) => x,
            _ => panic!("option `{}` has no float default", self.key),
        }
    }

    /// The default of an integer option.
    pub fn usize(&self) -> usize {
        match self.default {
            Value::Int(i) => i as usize,
            _ => panic!("option `{}` has no integer default", self.key),
        }
    }

    /// The default of a boolean option.
    pub fn bool(&self) -> bool {
        match self.default {
            Value::Bool(b) => b,
            _ => panic!("option `{}` has no boolean default", self.key),
        }
    }

    /// The default of a choice.
    pub fn name(&self) -> &str {
        match &self.default {
            Value::Str(s) => s.as_ref(),
            _ => panic!("option `{}` has no name default", self.key),
        }
    }
}

/// A number as the docs write it (`1e-08` as `1e-8`, `inf`).
fn fmt_num(x: f64) -> String {
    if x.is_infinite() {
        return if x > 0.0 { "inf".into() } else { "-inf".into() };
    }
    if x != 0.0 && (x.abs() >= 1e5 || x.abs() < 1e-3) {
        let s = format!("{x:e}");
        return s;
    }
    format!("{x}")
}

/// The spec of `key` in a table (panics for an unknown key: the tables are the crate's own).
pub fn spec<'a>(table: &'a [OptionSpec], key: &str) -> &'a OptionSpec {
    table.iter().find(|s| s.key == key).unwrap_or_else(|| panic!("no option `{key}` in its table"))
}

/// A map of option values by key.
pub type OptionMap = BTreeMap<String, Value>;

/// A configuration struct whose fields are options.
pub trait Configurable {
    /// The options of the struct, in the order of the docs.
    fn options() -> &'static [OptionSpec];
    /// The value of the field of `key` (a key of [`Configurable::options`]).
    fn get(&self, key: &str) -> Value;
    /// Sets the field of `key` to `value`, already checked against its spec.
    fn set(&mut self, key: &str, value: &Value) -> Result<()>;
}

/// Checks every field of `c` against its spec.
pub fn validate_all<C: Configurable>(c: &C) -> Result<()> {
    for s in C::options() {
        s.check(&c.get(s.key))?;
    }
    Ok(())
}

/// Sets the fields of `c` whose keys are in `map` (checked against their specs); the other keys
/// are left for other rooms. Returns the number of keys used.
pub fn apply<C: Configurable>(c: &mut C, map: &OptionMap) -> Result<usize> {
    let mut used = 0;
    for s in C::options() {
        if let Some(v) = map.get(s.key) {
            let v = s.check(v)?;
            c.set(s.key, &v)?;
            used += 1;
        }
    }
    Ok(used)
}

/// Every option of `c` with its value.
pub fn to_map<C: Configurable>(c: &C) -> OptionMap {
    C::options().iter().map(|s| (s.key.to_string(), c.get(s.key))).collect()
}

/// The string of a checked choice value.
pub fn as_name(v: &Value) -> &str {
    match v {
        Value::Str(s) => s.as_ref(),
        _ => "",
    }
}

/// The float of a checked float value (None for [`Value::None`]).
pub fn as_opt_f64(v: &Value) -> Option<f64> {
    v.as_f64()
}

/// The integer of a checked integer value (0 for anything else).
pub fn as_usize(v: &Value) -> usize {
    match v {
        Value::Int(i) => *i as usize,
        _ => 0,
    }
}

/// The boolean of a checked boolean value.
pub fn as_bool(v: &Value) -> bool {
    matches!(v, Value::Bool(true))
}

/// An error for a key no room knows, listing the keys allowed.
pub fn unknown_key(key: &str, allowed: &[&OptionSpec]) -> Error {
    let names: Vec<&str> = allowed.iter().map(|s| s.key).collect();
    Error::param("options", key, &format!("an option key, one of {}", names.join(", ")))
}

#[cfg(test)]
mod tests {
    use super::*;

    const X: OptionSpec = float("t", "x", 0.5, 0.0, 1.0, "1", "a fraction").open(false, true);

    #[test]
    fn float_range_and_its_ends() {
        assert_eq!(X.check(&Value::Float(0.0)).unwrap(), Value::Float(0.0));
        assert_eq!(X.check(&Value::Int(0)).unwrap(), Value::Float(0.0));
        let e = X.check(&Value::Float(1.0)).unwrap_err().to_string();
        assert!(e.contains("`x`") && e.contains("[0, 1)"), "{e}");
        assert!(X.check(&Value::Float(f64::NAN)).is_err());
        assert!(X.check(&Value::Bool(true)).is_err());
        assert!(X.check(&Value::None).is_err());
        assert!(X.off_by_default().check(&Value::None).is_ok());
    }

    #[test]
    fn infinite_end_included_admits_infinity() {
        let s = float("t", "max_dt", f64::INFINITY, 0.0, f64::INFINITY, "s", "cap").open(true, false);
        assert!(s.check(&Value::Float(f64::INFINITY)).is_ok());
        assert!(s.check(&Value::Float(0.0)).is_err());
    }
}
