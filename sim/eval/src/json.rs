//! Reading a results folder's JSON files back into the types they were written from.
//!
//! A renamed or retyped field is an error here, naming the file, the line and the field's
//! path in the document (`slam.robots.dala: missing field `events``, through
//! `serde_path_to_error`), not a missing key found later by a caller.

use crate::EvalError;
use hetsim_core::files::FileError;
use serde::de::DeserializeOwned;
use std::path::Path;

/// The JSON file at `path` as a `T`.
pub fn read<T: DeserializeOwned>(path: &Path) -> Result<T, EvalError> {
    let bytes = std::fs::read(path).map_err(FileError::at(path))?;
    parse(path, &bytes)
}

/// `bytes`, the content of the JSON file at `path`, as a `T`.
pub fn parse<T: DeserializeOwned>(path: &Path, bytes: &[u8]) -> Result<T, EvalError> {
    let mut de = serde_json::Deserializer::from_slice(bytes);
    let value = serde_path_to_error::deserialize(&mut de).map_err(|source| EvalError::Parse {
        path: path.to_path_buf(),
        source,
    })?;
    // Trailing content after the document is refused, as `serde_json::from_slice` does.
    de.end().map_err(|e| EvalError::Content {
        path: path.to_path_buf(),
        message: format!("line {}: content after the JSON document: {e}", e.line()),
    })?;
    Ok(value)
}
