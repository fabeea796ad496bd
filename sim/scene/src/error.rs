//! Errors that point at the offending place in a file.

use std::fmt;
use std::path::{Path, PathBuf};

/// A problem with a scenario or robot file, or with what it asks for.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SceneError {
    /// A file could not be read.
    #[error("{}: cannot read: {reason}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// The operating system's reason.
        reason: String,
    },
    /// A field has a value that is not allowed (or a field is unknown, missing, or of the
    /// wrong type).
    #[error("{0}")]
    Field(FieldError),
}

/// Where and what: file, line, field, value, and what would be allowed.
#[derive(Debug, Clone, PartialEq)]
pub struct FieldError {
    /// The file the problem is in.
    pub file: PathBuf,
    /// 1-based line, when known.
    pub line: Option<usize>,
    /// Dotted path of the field, for example `robots[1].start`.
    pub field: String,
    /// The offending value as written (or `(missing)`).
    pub value: String,
    /// What is allowed instead.
    pub allowed: String,
}

impl fmt::Display for FieldError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file.display())?;
        if let Some(line) = self.line {
            write!(f, ":{line}")?;
        }
        write!(
            f,
            ": field `{}` = {}: {}",
            self.field, self.value, self.allowed
        )
    }
}

impl SceneError {
    /// A field error.
    pub fn field(
        file: &Path,
        line: Option<usize>,
        field: impl Into<String>,
        value: impl fmt::Display,
        allowed: impl Into<String>,
    ) -> Self {
        SceneError::Field(FieldError {
            file: file.to_path_buf(),
            line,
            field: field.into(),
            value: value.to_string(),
            allowed: allowed.into(),
        })
    }

    /// The field error inside, if this is one.
    pub fn as_field(&self) -> Option<&FieldError> {
        match self {
            SceneError::Field(e) => Some(e),
            SceneError::Read { .. } => None,
        }
    }
}
