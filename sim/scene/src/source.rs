//! A TOML source file kept beside what was parsed from it, to point errors at lines.

use crate::SceneError;
use serde::de::DeserializeOwned;
use std::ops::Range;
use std::path::{Path, PathBuf};
use toml_edit::{Item, Value};

/// The schema version every scenario and robot file must declare.
pub const SCHEMA_VERSION: i64 = 1;

/// One loaded file: its path, text and span-carrying syntax tree.
pub struct Source {
    path: PathBuf,
    text: String,
    doc: toml_edit::Document<String>,
}

impl Source {
    /// Reads and parses a file (syntax only).
    pub fn read(path: &Path) -> Result<Self, SceneError> {
        let text = std::fs::read_to_string(path).map_err(|e| SceneError::Read {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })?;
        Self::from_text(path, text)
    }

    /// Parses text that came from `path` (syntax only).
    pub fn from_text(path: &Path, text: String) -> Result<Self, SceneError> {
        match toml_edit::Document::parse(text.clone()) {
            Ok(doc) => Ok(Self {
                path: path.to_path_buf(),
                text,
                doc,
            }),
            Err(e) => {
                let line = e.span().map(|s| line_of_offset(&text, s.start));
                Err(SceneError::field(
                    path,
                    line,
                    "(syntax)",
                    excerpt(&text, line),
                    format!("valid TOML: {}", e.message()),
                ))
            }
        }
    }

    /// The file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The file's text.
    pub fn text(&self) -> &str {
        &self.text
    }

    /// Checks `schema_version`, then deserializes into `T`, mapping serde errors (unknown
    /// fields, wrong types, missing fields) to the line they occur on.
    pub fn parse<T: DeserializeOwned>(&self) -> Result<T, SceneError> {
        self.check_version()?;
        toml::from_str::<T>(&self.text).map_err(|e| self.serde_error(&e))
    }

    fn check_version(&self) -> Result<(), SceneError> {
        let item = self.doc.as_table().get("schema_version");
        match item.and_then(Item::as_integer) {
            Some(SCHEMA_VERSION) => Ok(()),
            _ => Err(SceneError::field(
                &self.path,
                self.line(&["schema_version"]).or(Some(1)),
                "schema_version",
                item.map_or("(missing)".to_string(), |i| {
                    i.to_string().trim().to_string()
                }),
                format!("schema_version = {SCHEMA_VERSION}, the only version this hetsim reads"),
            )),
        }
    }

    fn serde_error(&self, e: &toml::de::Error) -> SceneError {
        let line = e.span().map(|s| line_of_offset(&self.text, s.start));
        let source_line = excerpt(&self.text, line);
        let message = e.message().trim().to_string();
        // The field is the key on the offending line when there is one.
        let field = source_line
            .split_once('=')
            .map(|(k, _)| k.trim().trim_matches('"').to_string())
            .filter(|k| !k.is_empty() && !k.starts_with('['))
            .or_else(|| message.split('`').nth(1).map(str::to_string))
            .unwrap_or_else(|| "(table)".to_string());
        SceneError::field(&self.path, line, field, source_line, message)
    }

    /// The 1-based line of the item at a path (`["robots", "1", "start"]`), or of its deepest
    /// existing ancestor.
    pub fn line(&self, path: &[&str]) -> Option<usize> {
        self.line_in_table(self.doc.as_table(), path, None)
    }

    fn to_line(&self, span: Option<Range<usize>>) -> Option<usize> {
        span.map(|s| line_of_offset(&self.text, s.start))
    }

    fn line_in_table(
        &self,
        table: &toml_edit::Table,
        rest: &[&str],
        span: Option<Range<usize>>,
    ) -> Option<usize> {
        let Some((key, tail)) = rest.split_first() else {
            return self.to_line(span);
        };
        match table.get(key) {
            Some(Item::Table(t)) => self.line_in_table(t, tail, t.span().or(span)),
            Some(Item::Value(v)) => self.line_in_value(v, tail, v.span().or(span)),
            Some(Item::ArrayOfTables(a)) => {
                let span = a.span().or(span);
                match tail.split_first() {
                    Some((index, tail)) => match index.parse::<usize>().ok().and_then(|i| a.get(i))
                    {
                        Some(t) => self.line_in_table(t, tail, t.span().or(span)),
                        None => self.to_line(span),
                    },
                    None => self.to_line(span),
                }
            }
            Some(Item::None) | None => self.to_line(span),
        }
    }

    fn line_in_value(
        &self,
        value: &Value,
        rest: &[&str],
        span: Option<Range<usize>>,
    ) -> Option<usize> {
        let Some((key, tail)) = rest.split_first() else {
            return self.to_line(span);
        };
        match value_child(value, key) {
            Some(v) => self.line_in_value(v, tail, v.span().or(span)),
            None => self.to_line(span),
        }
    }
}

fn value_child<'a>(value: &'a Value, key: &str) -> Option<&'a Value> {
    match value {
        Value::InlineTable(t) => t.get(key),
        Value::Array(a) => key.parse::<usize>().ok().and_then(|i| a.get(i)),
        _ => None,
    }
}

/// 1-based line of a byte offset.
pub fn line_of_offset(text: &str, offset: usize) -> usize {
    text[..offset.min(text.len())].matches('\n').count() + 1
}

/// The trimmed text of a 1-based line, or `""`.
fn excerpt(text: &str, line: Option<usize>) -> String {
    line.and_then(|l| text.lines().nth(l - 1))
        .map(|s| s.trim().to_string())
        .unwrap_or_default()
}
