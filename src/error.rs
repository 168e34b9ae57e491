//! The library's error type. Every variant is something a user can act on: it names the file or
//! field at fault and what is allowed.

use std::path::PathBuf;

/// Errors of the bfqi-ga library.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A setting is outside its allowed range.
    #[error("invalid {field} = {value}: {allowed}")]
    Invalid {
        /// Dotted path of the field, e.g. `mlp.delta_min`.
        field: String,
        /// The offending value, as written.
        value: String,
        /// What is allowed, e.g. `must be ≥ 0`.
        allowed: String,
    },
    /// An environment name that is not one of ours.
    #[error("unknown environment '{name}': valid names are {valid}")]
    UnknownEnv {
        /// What the user typed.
        name: String,
        /// The valid names, comma-separated.
        valid: String,
    },
    /// Data handed to a learner or to FQI is unusable (NaN, wrong shape, empty).
    #[error("bad data: {0}")]
    Data(String),
    /// A file could not be read or written.
    #[error("{path}: {err}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What the OS said (part of the message, not a separate cause, so it prints once).
        err: std::io::Error,
    },
    /// A spec, config or result file is malformed.
    #[error("{path}: {message}")]
    File {
        /// The file.
        path: PathBuf,
        /// What is wrong, naming the field.
        message: String,
    },
}

impl Error {
    /// Shorthand for [`Error::Invalid`].
    pub fn invalid(field: impl Into<String>, value: impl ToString, allowed: impl Into<String>) -> Self {
        Error::Invalid { field: field.into(), value: value.to_string(), allowed: allowed.into() }
    }

    /// Shorthand for [`Error::Io`].
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io { path: path.into(), err: source }
    }

    /// Prefixes the field path of an [`Error::Invalid`] with `prefix.` (used when a nested config is
    /// validated inside a larger one, so the message names the full path).
    pub fn within(self, prefix: &str) -> Self {
        match self {
            Error::Invalid { field, value, allowed } => {
                Error::Invalid { field: format!("{prefix}.{field}"), value, allowed }
            }
            other => other,
        }
    }
}

/// Deserialises a JSON value read from `origin`; an error names the file and the field path
/// (`field search.ga.population: invalid type …`), after `context` (e.g. `job 2 (c): `).
pub fn from_json<T: serde::de::DeserializeOwned>(
    value: serde_json::Value,
    origin: &std::path::Path,
    context: &str,
) -> Result<T> {
    serde_path_to_error::deserialize(value).map_err(|e| {
        let path = e.path().to_string();
        let inner = e.into_inner().to_string();
        let message = if path == "." { format!("{context}{inner}") } else { format!("{context}field {path}: {inner}") };
        Error::File { path: origin.to_path_buf(), message }
    })
}

/// The library's result type.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Checks a condition on a field; returns [`Error::Invalid`] if it fails.
pub fn ensure(ok: bool, field: &str, value: impl ToString, allowed: &str) -> Result<()> {
    if ok { Ok(()) } else { Err(Error::invalid(field, value, allowed)) }
}
