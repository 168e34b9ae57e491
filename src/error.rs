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
    /// A run failed or a check disagreed (exit 1, where bad input is exit 2).
    #[error("{0}")]
    Failed(String),
    /// A command line the library refuses as a whole: flags that do not go together, or a value in
    /// a form it cannot read (worded for the command line).
    #[error("{0}")]
    Usage(String),
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
        Error::Invalid { field: field.into(), value: short_number(value.to_string()), allowed: allowed.into() }
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
pub fn from_json<T: serde::de::DeserializeOwned + serde::Serialize>(
    value: serde_json::Value,
    origin: &std::path::Path,
    context: &str,
) -> Result<T> {
    let t: T = serde_path_to_error::deserialize(value.clone()).map_err(|e| {
        let (path, inner) = joined(e);
        let message = if path == "." { format!("{context}{inner}") } else { format!("{context}field {path}: {inner}") };
        Error::File { path: origin.to_path_buf(), message }
    })?;
    // serde reads an array as a struct's fields in order, so `"network": []` would silently be
    // the default network: where what was read writes back as an object, an array is refused.
    if let Ok(read) = serde_json::to_value(&t)
        && let Some(path) = array_for_object(&value, &read, String::new())
    {
        let message = format!("{context}field {path}: must be a JSON object, not an array");
        return Err(Error::File { path: origin.to_path_buf(), message });
    }
    Ok(t)
}

/// Parses JSON text read from `origin` as a `T`; an error names the file and the field path
/// (`field env.g: invalid type …`) after `context`, as [`from_json`] does, so the markers that
/// carry a [`tagged`] enum's inner path never reach a message.
pub fn from_json_text<T: serde::de::DeserializeOwned>(
    text: &str,
    origin: &std::path::Path,
    context: &str,
) -> Result<T> {
    let file = |message: String| Error::File { path: origin.to_path_buf(), message };
    let mut de = serde_json::Deserializer::from_str(text);
    let t: T = serde_path_to_error::deserialize(&mut de).map_err(|e| {
        let (path, inner) = joined(e);
        file(if path == "." { format!("{context}{inner}") } else { format!("{context}field {path}: {inner}") })
    })?;
    de.end().map_err(|e| file(format!("{context}{e}")))?;
    Ok(t)
}

/// The first field path at which `given` holds an array where `read` (the same document as
/// deserialised and written back) holds an object.
fn array_for_object(given: &serde_json::Value, read: &serde_json::Value, path: String) -> Option<String> {
    use serde_json::Value::{Array, Object};
    let join = |key: &str| if path.is_empty() { key.to_string() } else { format!("{path}.{key}") };
    match (given, read) {
        (Array(_), Object(_)) => Some(if path.is_empty() { ".".into() } else { path }),
        (Object(g), Object(r)) => g.iter().find_map(|(k, v)| r.get(k).and_then(|rv| array_for_object(v, rv, join(k)))),
        (Array(g), Array(r)) => {
            g.iter().zip(r).enumerate().find_map(|(i, (v, rv))| array_for_object(v, rv, format!("{path}[{i}]")))
        }
        _ => None,
    }
}

/// Refuses a JSON document that is not an object (serde would read an array as a struct's fields
/// in order and report a confusing `field [0]`).
pub fn expect_object(value: &serde_json::Value, origin: &std::path::Path, what: &str) -> Result<()> {
    let kind = match value {
        serde_json::Value::Object(_) => return Ok(()),
        serde_json::Value::Array(_) => "an array",
        serde_json::Value::String(_) => "a string",
        serde_json::Value::Number(_) => "a number",
        serde_json::Value::Bool(_) => "a boolean",
        serde_json::Value::Null => "null",
    };
    Err(Error::File { path: origin.to_path_buf(), message: format!("{what} must be a JSON object, not {kind}") })
}

/// Separates an inner field path carried in a custom error message (see [`tagged`]).
const INNER: char = '\u{1}';

/// The full field path of a path-tracking error and its message, joining the path that a
/// [`tagged`] enum's fields report from inside.
fn joined(e: serde_path_to_error::Error<serde_json::Error>) -> (String, String) {
    let outer = e.path().to_string();
    let inner = e.into_inner().to_string();
    // serde_json appends " at line … column …" to custom messages of its own parser only; from a
    // Value there is none, but a marker may sit after a prefix such as "invalid value: ".
    match inner.split_once(INNER).and_then(|(_, rest)| rest.split_once(INNER)) {
        Some((sub, message)) => {
            let path = if outer == "." { sub.to_string() } else { format!("{outer}.{sub}") };
            (path, message.to_string())
        }
        None => (outer, inner),
    }
}

/// Deserialises the fields of an internally tagged enum's variant (`{"name": "cartpole", ...}`)
/// from what remains of its object, keeping the path of a bad field (`env.g`, not `env`): serde's
/// derived internally tagged enums buffer their content and lose it.
pub(crate) fn tagged<T: serde::de::DeserializeOwned, E: serde::de::Error>(
    rest: serde_json::Map<String, serde_json::Value>,
) -> std::result::Result<T, E> {
    serde_path_to_error::deserialize(serde_json::Value::Object(rest)).map_err(|e| {
        let (path, inner) = joined(e);
        if path == "." { E::custom(inner) } else { E::custom(format!("{INNER}{path}{INNER}{inner}")) }
    })
}

/// Splits the tag off an internally tagged enum's object: `(tag value, the other fields)`.
pub(crate) fn take_tag<'de, D: serde::Deserializer<'de>>(
    d: D,
    tag: &'static str,
) -> std::result::Result<(String, serde_json::Map<String, serde_json::Value>), D::Error> {
    use serde::Deserialize;
    use serde::de::Error as _;
    let mut map = serde_json::Map::<String, serde_json::Value>::deserialize(d)?;
    match map.remove(tag) {
        Some(serde_json::Value::String(s)) => Ok((s, map)),
        Some(other) => Err(D::Error::custom(format!("{INNER}{tag}{INNER}must be a string, not {other}"))),
        None => Err(D::Error::missing_field(tag)),
    }
}

/// Refuses an internally tagged enum's tag value that names no variant, with the tag in the field
/// path (`env.name: unknown variant …`, not `env: …`): the tag is a field the user wrote.
pub(crate) fn unknown_tag<E: serde::de::Error>(tag: &str, value: &str, variants: &'static [&'static str]) -> E {
    use serde::de::Error as _;
    let message = serde::de::value::Error::unknown_variant(value, variants).to_string();
    E::custom(format!("{INNER}{tag}{INNER}{message}"))
}

/// A number as a person reads it: `1e308`, not the 309 digits `f64`'s `Display` writes.
pub(crate) fn short_number(s: String) -> String {
    match s.parse::<f64>() {
        Ok(x) if s.len() > 24 && x.is_finite() => format!("{x:e}"),
        _ => shortened(s),
    }
}

/// A value as errors echo it: at most [`ECHOED`] characters, the rest counted (a 100,000-character
/// id is not a 400 kB line).
pub(crate) fn shortened(s: String) -> String {
    match s.char_indices().nth(ECHOED) {
        Some((at, _)) => format!("{}… ({} characters)", &s[..at], s.chars().count()),
        None => s,
    }
}

/// The most characters of a value an error echoes.
pub(crate) const ECHOED: usize = 200;

/// The library's result type.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Checks a condition on a field; returns [`Error::Invalid`] if it fails.
pub fn ensure(ok: bool, field: &str, value: impl ToString, allowed: &str) -> Result<()> {
    if ok { Ok(()) } else { Err(Error::invalid(field, value, allowed)) }
}
