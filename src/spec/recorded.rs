//! A run directory's spec, read as it was recorded (`spec.json`): nothing is probed or re-read.

use super::{Spec, file_error};
use crate::error::Result;
use crate::store;
use std::path::Path;

impl Spec {
    /// Reads the resolved spec a run directory records (`spec.json`), as written: a gymnasium
    /// env's spaces and logged data's hash, episodes and slots are already in it, so no worker is
    /// started and no data read. The data hash is checked where datasets are made (a resume, a
    /// reproduction); reading a run needs neither its env's Python nor its data.
    pub fn load_recorded(path: &Path) -> Result<Spec> {
        let value = Self::parse_value(&store::read_input(path)?, path)?;
        crate::error::expect_object(&value, path, "a spec")?;
        let spec: Spec = crate::error::from_json(value, path, "")?;
        if let Some(g) = spec.env.env().gymnasium()
            && g.probed.is_none()
        {
            return Err(file_error(path, "env.probed is missing: a run's spec records its env's spaces".into()));
        }
        if let Some(d) = &spec.data
            && (d.hash.is_none() || d.episodes.is_none())
        {
            return Err(file_error(path, "data.hash or data.episodes is missing: a run's spec records them".into()));
        }
        spec.validate().map_err(|e| file_error(path, e.to_string()))?;
        Ok(spec)
    }
}
