//! The one TOML overlay of the host tools: a settings file's keys laid over the embedded
//! defaults that are its schema (the simulation's `default.toml`, the synthesis task's
//! `thesis.toml`).
//!
//! The defaults are the schema: a key that they do not have is unknown, a value must have
//! the type of the default it replaces (an integer may stand for a float), a table is
//! overlaid key by key, and an array keeps the length of its default unless the caller
//! names it as variable (its elements then take the type of the default's first element).
//! Every error names the key by its dotted path (`control.rate_hz`,
//! `scenario.step.steps_mm_deg[0]`).

use thiserror::Error;
use toml::{Table, Value};

/// Why a settings file's value cannot replace its default.
#[derive(Clone, Debug, PartialEq, Eq, Error)]
pub enum OverlayError {
    /// The defaults have no such key.
    #[error("unknown key `{key}` (known here: {})", known.join(", "))]
    UnknownKey {
        /// The key's dotted path.
        key: String,
        /// The keys of the table it was given in.
        known: Vec<String>,
    },
    /// The value has another type than its default.
    #[error("`{key}` must be {expected}, not {found}")]
    WrongType {
        key: String,
        /// The default's type, e.g. "a number".
        expected: &'static str,
        /// The value's type.
        found: &'static str,
    },
    /// An array of fixed length with another length.
    #[error("`{key}` must have {expected} elements, not {found}")]
    WrongLength {
        key: String,
        expected: usize,
        found: usize,
    },
}

/// A value's type for people: "a number", "a table", ...
pub fn type_name(v: &Value) -> &'static str {
    match v {
        Value::String(_) => "a string",
        Value::Integer(_) => "an integer",
        Value::Float(_) => "a number",
        Value::Boolean(_) => "true or false",
        Value::Datetime(_) => "a date",
        Value::Array(_) => "an array",
        Value::Table(_) => "a table",
    }
}

/// Overlays the keys of `user` onto `base` (the defaults). `variable_length` names the
/// arrays (dotted paths) that may have another length than their default.
pub fn overlay(
    base: &mut Table,
    user: Table,
    variable_length: &[&str],
) -> Result<(), OverlayError> {
    overlay_at("", base, user, variable_length)
}

fn overlay_at(
    prefix: &str,
    base: &mut Table,
    user: Table,
    variable_length: &[&str],
) -> Result<(), OverlayError> {
    for (k, v) in user {
        let key = if prefix.is_empty() {
            k.clone()
        } else {
            format!("{prefix}.{k}")
        };
        let Some(default) = base.get(&k) else {
            return Err(OverlayError::UnknownKey {
                key,
                known: base.keys().cloned().collect(),
            });
        };
        let merged = conform(&key, default, v, variable_length)?;
        base.insert(k, merged);
    }
    Ok(())
}

/// Checks `value` against the schema value `default` and returns the value to store.
fn conform(
    key: &str,
    default: &Value,
    value: Value,
    variable_length: &[&str],
) -> Result<Value, OverlayError> {
    match (default, value) {
        (Value::Table(d), Value::Table(v)) => {
            let mut out = d.clone();
            overlay_at(key, &mut out, v, variable_length)?;
            Ok(Value::Table(out))
        }
        (Value::Float(_), Value::Integer(i)) => Ok(Value::Float(i as f64)),
        (Value::Array(d), Value::Array(v)) => {
            if !variable_length.contains(&key) && d.len() != v.len() {
                return Err(OverlayError::WrongLength {
                    key: key.to_string(),
                    expected: d.len(),
                    found: v.len(),
                });
            }
            // The elements must have the type of the default's first element.
            let Some(proto) = d.first() else {
                return Ok(Value::Array(v));
            };
            v.into_iter()
                .enumerate()
                .map(|(i, x)| conform(&format!("{key}[{i}]"), proto, x, variable_length))
                .collect::<Result<Vec<_>, _>>()
                .map(Value::Array)
        }
        (d, v) if std::mem::discriminant(d) == std::mem::discriminant(&v) => Ok(v),
        (d, v) => Err(OverlayError::WrongType {
            key: key.to_string(),
            expected: type_name(d),
            found: type_name(&v),
        }),
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;

    const DEFAULTS: &str = "[a]\nx = 1.0\nn = 3\nfixed = [1.0, 2.0]\nlist = [[1.0, 2.0]]\n";

    fn over(user: &str) -> Result<Table, OverlayError> {
        let mut base: Table = DEFAULTS.parse().unwrap();
        overlay(&mut base, user.parse().unwrap(), &["a.list"])?;
        Ok(base)
    }

    #[test]
    fn only_the_given_keys_change_and_integers_stand_for_floats() {
        let t = over("[a]\nx = 2\n").unwrap();
        let a = t["a"].as_table().unwrap();
        assert_eq!(a["x"], Value::Float(2.0));
        assert_eq!(a["n"], Value::Integer(3));
        let t = over("[a]\nlist = [[1, 2], [3, 4], [5, 6]]\n").unwrap();
        assert_eq!(t["a"]["list"].as_array().unwrap().len(), 3);
    }

    #[test]
    fn errors_name_the_key_by_its_dotted_path() {
        assert_eq!(
            over("[a]\ny = 1\n").unwrap_err().to_string(),
            "unknown key `a.y` (known here: fixed, list, n, x)"
        );
        assert_eq!(
            over("[a]\nn = 1.5\n").unwrap_err().to_string(),
            "`a.n` must be an integer, not a number"
        );
        assert_eq!(
            over("[a]\nfixed = [1.0]\n").unwrap_err().to_string(),
            "`a.fixed` must have 2 elements, not 1"
        );
        assert_eq!(
            over("[a]\nlist = [[1.0]]\n").unwrap_err().to_string(),
            "`a.list[0]` must have 2 elements, not 1"
        );
        assert_eq!(
            over("a = 1\n").unwrap_err().to_string(),
            "`a` must be a table, not an integer"
        );
    }
}
