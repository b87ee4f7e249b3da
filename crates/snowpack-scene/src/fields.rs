//! Typed extraction from a TOML table that tracks the key path (for messages)
//! and rejects keys nobody asked for.

use std::path::Path;

use glam::Vec3;
use toml::{Table, Value};

use crate::error::SceneError;

/// Largest magnitude of any number in a scene: well inside f32's range, so
/// that every number stays finite once converted and multiplied a little.
pub(crate) const MAX_MAGNITUDE: f64 = 1e12;

/// The remaining keys of one table, with its path.
pub(crate) struct Fields<'f> {
    file: &'f Path,
    path: String,
    table: Table,
}

fn type_name(v: &Value) -> &'static str {
    match v {
        Value::String(_) => "a string",
        Value::Integer(_) => "an integer",
        Value::Float(_) => "a float",
        Value::Boolean(_) => "a boolean",
        Value::Datetime(_) => "a date",
        Value::Array(_) => "an array",
        Value::Table(_) => "a table",
    }
}

impl<'f> Fields<'f> {
    pub(crate) fn new(file: &'f Path, path: impl Into<String>, table: Table) -> Self {
        Self { file, path: path.into(), table }
    }

    pub(crate) fn key(&self, key: &str) -> String {
        if self.path.is_empty() { key.to_owned() } else { format!("{}.{key}", self.path) }
    }

    pub(crate) fn err(&self, key: &str, message: impl Into<String>) -> SceneError {
        SceneError::new(self.file, self.key(key), message)
    }

    fn number(&self, key: &str, v: &Value) -> Result<f64, SceneError> {
        let x = match v {
            Value::Float(f) => *f,
            Value::Integer(i) => *i as f64,
            other => return Err(self.err(key, format!("expected a number, got {}", type_name(other)))),
        };
        if !x.is_finite() {
            return Err(self.err(key, format!("must be a finite number, got {x}")));
        }
        Ok(x)
    }

    /// A number as the f32 it is used as: finite as an f64 is not enough
    /// (`-1e39` is an infinite f32), so every number of a scene is at most
    /// [`MAX_MAGNITUDE`] in size.
    fn number_f32(&self, key: &str, v: &Value) -> Result<f32, SceneError> {
        let x = self.number(key, v)?;
        if x.abs() > MAX_MAGNITUDE {
            return Err(self.err(key, format!("{x} is out of range (numbers of a scene are at most {MAX_MAGNITUDE:e} in size)")));
        }
        Ok(x as f32)
    }

    pub(crate) fn f32_opt(&mut self, key: &str) -> Result<Option<f32>, SceneError> {
        let Some(v) = self.table.remove(key) else { return Ok(None) };
        self.number_f32(key, &v).map(Some)
    }

    pub(crate) fn f32(&mut self, key: &str, default: f32) -> Result<f32, SceneError> {
        Ok(self.f32_opt(key)?.unwrap_or(default))
    }

    /// A number > 0.
    pub(crate) fn positive(&mut self, key: &str, default: f32, unit: &str) -> Result<f32, SceneError> {
        let x = self.f32(key, default)?;
        if x <= 0.0 {
            return Err(self.err(key, format!("must be a positive number{unit}, got {x}")));
        }
        Ok(x)
    }

    /// A number >= 0.
    pub(crate) fn non_negative(&mut self, key: &str, default: f32, unit: &str) -> Result<f32, SceneError> {
        let x = self.f32(key, default)?;
        if x < 0.0 {
            return Err(self.err(key, format!("must be zero or positive{unit}, got {x}")));
        }
        Ok(x)
    }

    pub(crate) fn u32_in(&mut self, key: &str, default: u32, range: std::ops::RangeInclusive<u64>) -> Result<u32, SceneError> {
        let Some(v) = self.table.remove(key) else { return Ok(default) };
        let Value::Integer(i) = v else {
            return Err(self.err(key, format!("expected an integer, got {}", type_name(&v))));
        };
        match u64::try_from(i) {
            Ok(u) if range.contains(&u) => Ok(u as u32),
            _ => Err(self.err(key, format!("{i} is outside {}..={}", range.start(), range.end()))),
        }
    }

    pub(crate) fn bool(&mut self, key: &str, default: bool) -> Result<bool, SceneError> {
        match self.table.remove(key) {
            None => Ok(default),
            Some(Value::Boolean(b)) => Ok(b),
            Some(v) => Err(self.err(key, format!("expected true or false, got {}", type_name(&v)))),
        }
    }

    pub(crate) fn string_opt(&mut self, key: &str) -> Result<Option<String>, SceneError> {
        match self.table.remove(key) {
            None => Ok(None),
            Some(Value::String(s)) => Ok(Some(s)),
            Some(v) => Err(self.err(key, format!("expected a string, got {}", type_name(&v)))),
        }
    }

    /// A string from a fixed set of choices.
    pub(crate) fn choice(&mut self, key: &str, default: &str, choices: &[&str]) -> Result<String, SceneError> {
        let s = self.string_opt(key)?.unwrap_or_else(|| default.to_owned());
        if choices.contains(&s.as_str()) { Ok(s) } else { Err(self.err(key, format!("{s:?} is not one of {}", choices.join(", ")))) }
    }

    fn numbers(&self, key: &str, v: &Value, n: usize) -> Result<Vec<f32>, SceneError> {
        let Value::Array(items) = v else {
            return Err(self.err(key, format!("expected an array of {n} numbers, got {}", type_name(v))));
        };
        if items.len() != n {
            return Err(self.err(key, format!("expected {n} numbers, got {}", items.len())));
        }
        items.iter().map(|x| self.number_f32(key, x)).collect()
    }

    pub(crate) fn vec2_opt(&mut self, key: &str) -> Result<Option<[f32; 2]>, SceneError> {
        let Some(v) = self.table.remove(key) else { return Ok(None) };
        let n = self.numbers(key, &v, 2)?;
        Ok(Some([n[0], n[1]]))
    }

    pub(crate) fn vec3(&mut self, key: &str, default: Vec3) -> Result<Vec3, SceneError> {
        let Some(v) = self.table.remove(key) else { return Ok(default) };
        let n = self.numbers(key, &v, 3)?;
        Ok(Vec3::new(n[0], n[1], n[2]))
    }

    /// An array of strings.
    pub(crate) fn strings_opt(&mut self, key: &str) -> Result<Option<Vec<String>>, SceneError> {
        let Some(v) = self.table.remove(key) else { return Ok(None) };
        let Value::Array(items) = &v else {
            return Err(self.err(key, format!("expected an array of strings, got {}", type_name(&v))));
        };
        items
            .iter()
            .map(|x| match x {
                Value::String(s) => Ok(s.clone()),
                other => Err(self.err(key, format!("expected strings, got {}", type_name(other)))),
            })
            .collect::<Result<Vec<_>, _>>()
            .map(Some)
    }

    /// An array of `[a, b, c, d]` rows.
    pub(crate) fn rows4_opt(&mut self, key: &str) -> Result<Option<Vec<[f32; 4]>>, SceneError> {
        let Some(v) = self.table.remove(key) else { return Ok(None) };
        let Value::Array(rows) = &v else {
            return Err(self.err(key, format!("expected an array of [x, y, z, t] rows, got {}", type_name(&v))));
        };
        let mut out = Vec::with_capacity(rows.len());
        for (k, row) in rows.iter().enumerate() {
            let n = self.numbers(&format!("{key}[{k}]"), row, 4)?;
            out.push([n[0], n[1], n[2], n[3]]);
        }
        Ok(Some(out))
    }

    /// An array of `[a, b, c]` rows.
    pub(crate) fn rows3_opt(&mut self, key: &str) -> Result<Option<Vec<[f32; 3]>>, SceneError> {
        let Some(v) = self.table.remove(key) else { return Ok(None) };
        let Value::Array(rows) = &v else {
            return Err(self.err(key, format!("expected an array of [x, z, t] rows, got {}", type_name(&v))));
        };
        let mut out = Vec::with_capacity(rows.len());
        for (k, row) in rows.iter().enumerate() {
            let n = self.numbers(&format!("{key}[{k}]"), row, 3)?;
            out.push([n[0], n[1], n[2]]);
        }
        Ok(Some(out))
    }

    pub(crate) fn table(&mut self, key: &str) -> Result<Option<Fields<'f>>, SceneError> {
        match self.table.remove(key) {
            None => Ok(None),
            Some(Value::Table(t)) => Ok(Some(Fields::new(self.file, format!("[{key}]"), t))),
            Some(v) => Err(self.err(key, format!("expected a table [{key}], got {}", type_name(&v)))),
        }
    }

    pub(crate) fn tables(&mut self, key: &str) -> Result<Vec<Fields<'f>>, SceneError> {
        match self.table.remove(key) {
            None => Ok(Vec::new()),
            Some(Value::Array(items)) => items
                .into_iter()
                .enumerate()
                .map(|(k, v)| match v {
                    Value::Table(t) => Ok(Fields::new(self.file, format!("[[{key}]][{k}]"), t)),
                    other => Err(self.err(key, format!("expected [[{key}]] tables, got {}", type_name(&other)))),
                })
                .collect(),
            Some(v) => Err(self.err(key, format!("expected [[{key}]] tables, got {}", type_name(&v)))),
        }
    }

    /// Whether `key` is present and not yet taken.
    pub(crate) fn has(&self, key: &str) -> bool {
        self.table.contains_key(key)
    }

    /// Fails on any key that was not taken.
    pub(crate) fn finish(self) -> Result<(), SceneError> {
        match self.table.keys().next() {
            None => Ok(()),
            Some(k) => Err(SceneError::new(self.file, self.key(k), "unknown key (see docs/scene.md for the schema)")),
        }
    }
}
