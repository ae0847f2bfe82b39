//! The workflow on inputs that are files or bytes in memory, writing
//! nothing: what the Python package's `gyrocomp.gap` runs. The same steps
//! as `gyrocomp gap` ([`run_with`](super::run_with) and
//! [`trials::cli`](super::trials::cli)), the same [`Report`](super::Report)
//! that `report.json` is serialised from, and for several trials the same
//! [`Joint`] that `trials.json` holds.

use super::refdata::{self, Derived};
use super::trials::{self, Joint, Trial};
use super::{analyse_with, read, GapResult};
use crate::adis::Profile;
use crate::reference::refcsv;
use crate::sim::model::SensorModel;
use std::path::PathBuf;

/// One input: a file (read by the path readers) or its bytes in memory
/// (read by the from-bytes readers), `name` naming them in errors.
#[derive(Clone, Debug)]
pub enum Source {
    File(PathBuf),
    Bytes { name: String, bytes: Vec<u8> },
}

impl Source {
    /// What errors call it: the path, or the bytes' name.
    pub fn name(&self) -> String {
        match self {
            Source::File(p) => p.display().to_string(),
            Source::Bytes { name, .. } => name.clone(),
        }
    }

    fn measured(&self, profile: &Profile) -> Result<Vec<read::MeasRow>, String> {
        match self {
            Source::File(p) => read::read_measured(p, profile),
            Source::Bytes { name, bytes } => read::measured_from_bytes(bytes, name, profile),
        }
    }

    fn truth(&self) -> Result<(Vec<read::TruthIn>, bool), String> {
        match self {
            Source::File(p) => read::read_truth(p),
            Source::Bytes { name, bytes } => read::truth_from_bytes(bytes, name),
        }
    }

    fn reference(&self) -> Result<refcsv::Reference, String> {
        match self {
            Source::File(p) => refcsv::read_reference(p),
            Source::Bytes { name, bytes } => refcsv::reference_from_bytes(bytes, name),
        }
    }
}

/// Where a trial's truth comes from ([`Truth`](super::Truth) with sources).
#[derive(Clone, Debug)]
pub enum TruthSource {
    /// `truth.csv` as `gyrocomp simulate` writes it.
    Simulated(Source),
    /// Derived from a measured reference ([`refdata::from_reference`]).
    Reference { source: Source, bandwidth: f64 },
    /// A unit known to lie still ([`refdata::from_static`]).
    Static { bandwidth: f64 },
}

impl TruthSource {
    fn is_simulated(&self) -> bool {
        matches!(self, TruthSource::Simulated(_))
    }
}

/// Read the measured data and derive the truth.
pub fn load(measured: &Source, truth: &TruthSource, profile: &Profile) -> Result<Derived, String> {
    let meas = measured.measured(profile)?;
    match truth {
        TruthSource::Simulated(s) => {
            let (truth, truth_has_temp) = s.truth()?;
            Ok(Derived { meas, truth, truth_has_temp, info: refdata::Derivation::simulated() })
        }
        TruthSource::Reference { source, bandwidth } => {
            let r = source.reference()?;
            refdata::from_reference(&meas, &r, *bandwidth).map_err(|e| format!("{}: {e}", source.name()))
        }
        TruthSource::Static { bandwidth } => {
            refdata::from_static(&meas, *bandwidth).map_err(|e| format!("{} (--static): {e}", measured.name()))
        }
    }
}

/// One trial through the workflow (steps 1-5, nothing written).
pub fn trial(name: &str, measured: &Source, truth: &TruthSource, base: &SensorModel, profile: &Profile) -> Result<Trial, String> {
    let data = load(measured, truth, profile)?;
    let derived = (!truth.is_simulated()).then_some(&data.info);
    let result: GapResult = analyse_with(&data.meas, &data.truth, data.truth_has_temp, base, profile, derived)?;
    Ok(Trial { name: name.to_string(), data, result })
}

/// What [`analyse`] gives: each trial's own run and, for several, their joint analysis.
pub struct Analysis {
    pub trials: Vec<Trial>,
    pub joint: Option<Joint>,
}

/// The trials' names as `gyrocomp gap` gives them (a file's folder or
/// stem, made unique); bytes are `trialN` (N from 1).
pub fn trial_names<'a>(measured: impl IntoIterator<Item = &'a Source>) -> Vec<String> {
    let paths: Vec<PathBuf> = measured
        .into_iter()
        .enumerate()
        .map(|(k, s)| match s {
            Source::File(p) => p.clone(),
            Source::Bytes { .. } => PathBuf::from(format!("trial{}", k + 1)),
        })
        .collect();
    trials::trial_names(&paths)
}

/// The workflow on one trial or several (then also consistency, the joint
/// model and leave-one-trial-out). An error names the trial when there are
/// several.
pub fn analyse(inputs: &[(Source, TruthSource)], base: &SensorModel, profile: &Profile) -> Result<Analysis, String> {
    if inputs.is_empty() {
        return Err("no measured input".into());
    }
    if inputs.len() > 1 && inputs.iter().any(|(_, t)| t.is_simulated()) {
        return Err("several measured inputs need a measured reference each (or static), not a simulated truth".into());
    }
    let names = trial_names(inputs.iter().map(|i| &i.0));
    let several = inputs.len() > 1;
    let mut out = Vec::new();
    for ((m, t), name) in inputs.iter().zip(&names) {
        let tr = trial(name, m, t, base, profile).map_err(|e| if several { format!("{name}: {e}") } else { e })?;
        out.push(tr);
    }
    let joint = if several { Some(trials::joint(&out, base, profile)?) } else { None };
    Ok(Analysis { trials: out, joint })
}
