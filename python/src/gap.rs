//! `gyrocomp.gap`: what a gyro sensor model is missing, with evidence
//! (`gyrocomp gap`, docs/gap.md), on files or bytes. The analysis is the
//! crate's (`gap::inputs::analyse`); the dict is the `Report` that
//! `report.json` is serialised from (and for several trials what
//! `trials.json` holds), through JSON.

use gyrocomp::adis::builtin_profile;
use gyrocomp::gap::inputs::{analyse, Analysis, Source, TruthSource};
use gyrocomp::gap::refdata::{check_bandwidth, DEFAULT_BANDWIDTH_HZ};
use gyrocomp::gap::{load_base, parse_base, GapResult};
use gyrocomp::sim::model::SensorModel;
use pyo3::exceptions::{PyFileNotFoundError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyList, PyString, PyTuple};
use std::path::Path;

/// One input: bytes (named `what` in errors) or a path (str or os.PathLike) that must exist.
fn source(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Source> {
    if let Ok(b) = obj.downcast::<PyBytes>() {
        return Ok(Source::Bytes { name: what.to_string(), bytes: b.as_bytes().to_vec() });
    }
    let p = super::fspath(obj).map_err(|_| PyTypeError::new_err(format!("{what}: expected a path (str or os.PathLike) or bytes")))?;
    if !p.is_file() {
        return Err(PyFileNotFoundError::new_err(format!("{what}: {}: no such file", p.display())));
    }
    Ok(Source::File(p))
}

/// One input or a list of them (`what[k]` in errors).
fn sources(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<Source>> {
    if obj.downcast::<PyList>().is_ok() || obj.downcast::<PyTuple>().is_ok() {
        let items: Vec<Bound<'_, PyAny>> = obj.try_iter()?.collect::<PyResult<_>>()?;
        return items.iter().enumerate().map(|(k, o)| source(o, &format!("{what}[{k}]"))).collect();
    }
    Ok(vec![source(obj, what)?])
}

/// The base model of `model=None`: no effect, the default noise model; every effect is looked for.
const EMPTY_BASE: &str = "[gyro]\neffects = []\n";

/// The base model from None ([`EMPTY_BASE`]), TOML text
/// (str with a newline, `=` or `[`, or bytes) or a path (str or os.PathLike).
fn base_model(model: Option<&Bound<'_, PyAny>>) -> PyResult<SensorModel> {
    let err = |e: String| PyValueError::new_err(format!("model: {e}"));
    let Some(m) = model.filter(|m| !m.is_none()) else {
        return parse_base(EMPTY_BASE).map_err(err);
    };
    if let Ok(b) = m.downcast::<PyBytes>() {
        let s = std::str::from_utf8(b.as_bytes()).map_err(|e| PyValueError::new_err(format!("model: not UTF-8 text: {e}")))?;
        return parse_base(s).map_err(err);
    }
    if let Ok(s) = m.downcast::<PyString>() {
        let s = s.to_cow()?;
        if s.contains(['\n', '=', '[']) || s.trim().is_empty() {
            return parse_base(&s).map_err(err);
        }
    }
    let p = super::fspath(m).map_err(|_| PyTypeError::new_err("model: expected None, TOML text (str or bytes) or a path"))?;
    if !p.is_file() {
        return Err(PyFileNotFoundError::new_err(format!("model: {}: no such file", p.display())));
    }
    load_base(Path::new(&p)).map_err(|e| PyValueError::new_err(format!("model: {e}")))
}

/// The trials: each measured input with its truth (exactly one of truth, reference, static).
fn trials(
    measured: &Bound<'_, PyAny>,
    truth: Option<&Bound<'_, PyAny>>,
    reference: Option<&Bound<'_, PyAny>>,
    is_static: bool,
    bandwidth: f64,
) -> PyResult<Vec<(Source, TruthSource)>> {
    let truth = truth.filter(|t| !t.is_none());
    let reference = reference.filter(|r| !r.is_none());
    if [truth.is_some(), reference.is_some(), is_static].iter().filter(|x| **x).count() != 1 {
        return Err(PyValueError::new_err("give exactly one of truth= (simulated), reference= (measured) and static=True"));
    }
    let bandwidth = check_bandwidth(bandwidth).map_err(|e| PyValueError::new_err(e.replace("--bandwidth", "bandwidth =")))?;
    let meas = sources(measured, "measured")?;
    if meas.is_empty() {
        return Err(PyValueError::new_err("measured: no input"));
    }
    let truths: Vec<TruthSource> = if let Some(t) = truth {
        if meas.len() > 1 {
            return Err(PyValueError::new_err(
                "several measured inputs need a measured reference each (or static=True), not one simulated truth",
            ));
        }
        vec![TruthSource::Simulated(source(t, "truth")?)]
    } else if let Some(r) = reference {
        let refs = sources(r, "reference")?;
        if refs.len() != meas.len() {
            return Err(PyValueError::new_err(format!(
                "reference: {} input(s) for {} measured input(s): give one reference per trial, in the same order",
                refs.len(),
                meas.len()
            )));
        }
        refs.into_iter().map(|source| TruthSource::Reference { source, bandwidth }).collect()
    } else {
        meas.iter().map(|_| TruthSource::Static { bandwidth }).collect()
    };
    Ok(meas.into_iter().zip(truths).collect())
}

/// One trial's dict: report.json's keys, and `model`, the extended model as TOML (model.toml).
fn report_dict<'py>(py: Python<'py>, r: &GapResult) -> PyResult<Bound<'py, PyDict>> {
    let js = serde_json::to_string(&r.report).map_err(|e| PyValueError::new_err(e.to_string()))?;
    let d = py.import("json")?.call_method1("loads", (js,))?.downcast_into::<PyDict>()?;
    d.set_item("model", r.model.to_toml())?;
    Ok(d)
}

/// The result's dict: one trial's report, or for several the trials'
/// reports by name with trials.json's keys and the joint model.
fn result_dict<'py>(py: Python<'py>, a: &Analysis) -> PyResult<Bound<'py, PyDict>> {
    let Some(joint) = &a.joint else {
        return report_dict(py, &a.trials[0].result);
    };
    let js = serde_json::to_string(&joint.to_json()).map_err(|e| PyValueError::new_err(e.to_string()))?;
    let d = py.import("json")?.call_method1("loads", (js,))?.downcast_into::<PyDict>()?;
    let per = PyDict::new(py);
    for t in &a.trials {
        per.set_item(&t.name, report_dict(py, &t.result)?)?;
    }
    d.set_item("trials", per)?;
    d.set_item("model", joint.model.to_toml())?;
    Ok(d)
}

/// `gyrocomp gap` on files or bytes, nothing written. See docs/python.md.
#[pyfunction]
#[pyo3(signature = (measured, truth=None, reference=None, model=None, r#static=false, bandwidth=DEFAULT_BANDWIDTH_HZ, profile="adis16448"))]
#[pyo3(text_signature = "(measured, truth=None, reference=None, model=None, static=False, bandwidth=2.0, profile='adis16448')")]
#[allow(clippy::too_many_arguments)]
pub fn gap<'py>(
    py: Python<'py>,
    measured: &Bound<'py, PyAny>,
    truth: Option<&Bound<'py, PyAny>>,
    reference: Option<&Bound<'py, PyAny>>,
    model: Option<&Bound<'py, PyAny>>,
    r#static: bool,
    bandwidth: f64,
    profile: &str,
) -> PyResult<Bound<'py, PyDict>> {
    let prof = builtin_profile(profile).ok_or_else(|| {
        PyValueError::new_err(format!("profile {profile:?}: unknown (known: {})", gyrocomp::adis::BUILTIN_PROFILES.join(", ")))
    })?;
    let base = base_model(model)?;
    let inputs = trials(measured, truth, reference, r#static, bandwidth)?;
    let a = py.allow_threads(|| analyse(&inputs, &base, &prof)).map_err(PyValueError::new_err)?;
    result_dict(py, &a)
}
