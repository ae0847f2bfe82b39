//! Several trials of one unit (placeholder, filled next).
use std::path::{Path, PathBuf};

pub fn cli(_t: &[(PathBuf, super::Truth)], _model: &Path, _out: &Path, _profile: &str) -> Result<(), String> {
    Err("several trials: not yet".into())
}
