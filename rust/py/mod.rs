//! The Python boundary: the only module that knows pyo3 and numpy.
//!
//! Inputs are copied into owned buffers (so the interpreter can be released while the core
//! runs and no other thread can mutate them underneath), validated again here and in the core,
//! and every `CoreError` becomes the matching `robocal.exceptions` class. Outputs are new
//! C-order float64 arrays.

mod convert;

use crate::error::CoreError;
use crate::identify;
use crate::kalman;
use crate::kinematics::Chain;
use crate::measurement::{self, Batch, Measurement};
use crate::sigma;
use crate::solve::{self, Damping};
use convert::{array1, array2, core_err, index_array, index_list};
use numpy::{PyArray1, PyArray2, PyArray3, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// A compiled serial chain (see `docs/core-model.md`). Immutable and thread-safe.
#[pyclass(name = "Chain", module = "robocal._robocal", frozen)]
struct PyChain {
    inner: Chain,
}

type Arr1<'py> = Bound<'py, PyArray1<f64>>;
type Arr2<'py> = Bound<'py, PyArray2<f64>>;

fn matrix<'py>(py: Python<'py>, data: Vec<f64>, rows: usize, cols: usize) -> PyResult<Arr2<'py>> {
    PyArray1::from_vec(py, data).reshape([rows, cols])
}

/// A measurement call's inputs, copied out of Python so the interpreter can be released.
struct Owned {
    measurement: Measurement,
    params: Vec<f64>,
    q: Vec<f64>,
    y: Option<Vec<f64>>,
    m: usize,
}

impl Owned {
    /// The parameter columns `cols` names, all of them by default.
    fn columns(&self, cols: Option<&Bound<'_, PyAny>>) -> PyResult<Vec<usize>> {
        cols.map_or_else(|| Ok((0..self.params.len()).collect()), |c| index_list(c, "cols"))
    }

    fn batch<'a>(&'a self, chain: &'a Chain) -> crate::error::CoreResult<Batch<'a>> {
        Batch::new(chain, self.measurement, &self.params, &self.q, self.y.as_deref())
    }
}

impl PyChain {
    /// Parses the measurement name and copies `params` (P), `q` (m, N) and `y` (m, obs_width).
    fn owned(&self, measurement: &str, params: &Bound<'_, PyAny>, q: &Bound<'_, PyAny>, y: Option<&Bound<'_, PyAny>>) -> PyResult<Owned> {
        let measurement = Measurement::parse(measurement).map_err(core_err)?;
        let params = array1(params, "params", Some(self.inner.layout().n_params()))?;
        let (q, m, _) = array2(q, "q", Some(self.inner.n_joints()))?;
        let y = y.map(|y| array2(y, "y", Some(measurement.obs_width())).map(|a| a.0)).transpose()?;
        Ok(Owned { measurement, params, q, y, m })
    }
}

#[pymethods]
impl PyChain {
    #[new]
    fn new(conventions: Vec<String>, kinds: Vec<String>) -> PyResult<Self> {
        Ok(Self { inner: Chain::from_names(&conventions, &kinds).map_err(core_err)? })
    }

    #[getter]
    fn n_joints(&self) -> usize {
        self.inner.n_joints()
    }

    #[getter]
    fn n_params(&self) -> usize {
        self.inner.layout().n_params()
    }

    fn param_names(&self) -> Vec<String> {
        self.inner.layout().names_and_units().into_iter().map(|(n, _)| n).collect()
    }

    fn param_units(&self) -> Vec<&'static str> {
        self.inner.layout().names_and_units().into_iter().map(|(_, u)| u).collect()
    }

    /// Flange (or tool) poses, (m, 4, 4) in mm.
    #[pyo3(signature = (params, q, tool = false))]
    fn fk<'py>(
        &self,
        py: Python<'py>,
        params: &Bound<'py, PyAny>,
        q: &Bound<'py, PyAny>,
        tool: bool,
    ) -> PyResult<Bound<'py, PyArray3<f64>>> {
        let params = array1(params, "params", Some(self.inner.layout().n_params()))?;
        let (q, m, _) = array2(q, "q", Some(self.inner.n_joints()))?;
        // Filled in place: a zeroed Vec handed over with `from_vec` costs a pass over the whole
        // output (calloc's memset, or page faults on fresh pages) before the kernel writes it.
        // SAFETY: the array is new and not yet visible to Python; `fk_into` either writes every
        // element or fails before the array is returned.
        let out = unsafe { PyArray3::<f64>::new(py, [m, 4, 4], false) };
        let slice = unsafe { out.as_slice_mut() }.map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(e.to_string()))?;
        py.detach(|| self.inner.fk_into(&params, &q, tool, slice)).map_err(core_err)?;
        Ok(out)
    }

    /// Model predictions, (m, obs_width).
    fn predict<'py>(&self, py: Python<'py>, measurement: &str, params: &Bound<'py, PyAny>, q: &Bound<'py, PyAny>) -> PyResult<Arr2<'py>> {
        let inp = self.owned(measurement, params, q, None)?;
        let out = py.detach(|| inp.batch(&self.inner).map(|b| b.predict())).map_err(core_err)?;
        matrix(py, out, inp.m, inp.measurement.obs_width())
    }

    /// Residuals `y − h`, (m, res_width).
    fn residuals<'py>(
        &self,
        py: Python<'py>,
        measurement: &str,
        params: &Bound<'py, PyAny>,
        q: &Bound<'py, PyAny>,
        y: &Bound<'py, PyAny>,
    ) -> PyResult<Arr2<'py>> {
        let inp = self.owned(measurement, params, q, Some(y))?;
        let out = py.detach(|| inp.batch(&self.inner)?.residuals()).map_err(core_err)?;
        matrix(py, out, inp.m, inp.measurement.res_width())
    }

    /// Identification Jacobian `∂h/∂params[cols]`, (m·res_width, len(cols)).
    #[pyo3(signature = (measurement, params, q, y = None, cols = None))]
    fn jacobian<'py>(
        &self,
        py: Python<'py>,
        measurement: &str,
        params: &Bound<'py, PyAny>,
        q: &Bound<'py, PyAny>,
        y: Option<&Bound<'py, PyAny>>,
        cols: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Arr2<'py>> {
        let inp = self.owned(measurement, params, q, y)?;
        let cols = inp.columns(cols)?;
        let out = py.detach(|| inp.batch(&self.inner)?.jacobian(&cols)).map_err(core_err)?;
        matrix(py, out, inp.m * inp.measurement.res_width(), cols.len())
    }

    /// Residuals `y − h` (m, res_width) and the Jacobian of `jacobian` from one pass over the samples.
    #[pyo3(signature = (measurement, params, q, y, cols = None))]
    fn residuals_and_jacobian<'py>(
        &self,
        py: Python<'py>,
        measurement: &str,
        params: &Bound<'py, PyAny>,
        q: &Bound<'py, PyAny>,
        y: &Bound<'py, PyAny>,
        cols: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<(Arr2<'py>, Arr2<'py>)> {
        let inp = self.owned(measurement, params, q, Some(y))?;
        let cols = inp.columns(cols)?;
        let (r, j) = py.detach(|| inp.batch(&self.inner)?.residuals_and_jacobian(&cols)).map_err(core_err)?;
        let k = inp.measurement.res_width();
        Ok((matrix(py, r, inp.m, k)?, matrix(py, j, inp.m * k, cols.len())?))
    }

    /// Residuals of every sigma point, (S, m·res_width); `sigmas` (S, len(cols)) are absolute
    /// values of `params[cols]`.
    #[allow(clippy::too_many_arguments)] // the arguments are the Python method's signature
    fn sigma_residuals<'py>(
        &self,
        py: Python<'py>,
        measurement: &str,
        params: &Bound<'py, PyAny>,
        cols: &Bound<'py, PyAny>,
        sigmas: &Bound<'py, PyAny>,
        q: &Bound<'py, PyAny>,
        y: &Bound<'py, PyAny>,
    ) -> PyResult<Arr2<'py>> {
        let inp = self.owned(measurement, params, q, Some(y))?;
        let cols = index_list(cols, "cols")?;
        let (sigmas, s, _) = array2(sigmas, "sigmas", Some(cols.len()))?;
        let out = py.detach(|| measurement::sigma_residuals(&inp.batch(&self.inner)?, &cols, &sigmas)).map_err(core_err)?;
        matrix(py, out, s, inp.m * inp.measurement.res_width())
    }

    /// One UKF sweep over the samples (see `robocal.reference.ukf_sweep`): the state is
    /// `params[cols]` starting at `x` (n) with covariance `P` (n, n); `Q` (n, n) process noise per
    /// sample, `R` (k, k) measurement noise. Returns the new `(x, P)`.
    #[pyo3(signature = (measurement, params, cols, q, y, x, P, Q, R, alpha, beta, kappa))]
    #[allow(clippy::too_many_arguments, non_snake_case)]
    fn ukf_sweep<'py>(
        &self,
        py: Python<'py>,
        measurement: &str,
        params: &Bound<'py, PyAny>,
        cols: &Bound<'py, PyAny>,
        q: &Bound<'py, PyAny>,
        y: &Bound<'py, PyAny>,
        x: &Bound<'py, PyAny>,
        P: &Bound<'py, PyAny>,
        Q: &Bound<'py, PyAny>,
        R: &Bound<'py, PyAny>,
        alpha: f64,
        beta: f64,
        kappa: f64,
    ) -> PyResult<(Arr1<'py>, Arr2<'py>)> {
        let inp = self.owned(measurement, params, q, Some(y))?;
        let cols = index_list(cols, "cols")?;
        let x = array1(x, "x", Some(cols.len()))?;
        let n = cols.len();
        let (p, _, _) = array2(P, "P", Some(n))?;
        let (qn, _, _) = array2(Q, "Q", Some(n))?;
        let (r, _, _) = array2(R, "R", Some(inp.measurement.res_width()))?;
        let settings = kalman::UkfSettings { alpha, beta, kappa, q: &qn, r: &r };
        let (x, p) = py.detach(|| kalman::ukf_sweep(&inp.batch(&self.inner)?, &cols, &x, &p, &settings)).map_err(core_err)?;
        Ok((PyArray1::from_vec(py, x), matrix(py, p, n, n)?))
    }

    fn __repr__(&self) -> String {
        let joints: Vec<String> =
            self.inner.conventions().iter().zip(self.inner.kinds()).map(|(c, k)| format!("{c:?}/{k:?}").to_lowercase()).collect();
        format!("Chain([{}])", joints.join(", "))
    }
}

/// Merwe scaled sigma points around `x` (n) with covariance `P` (n, n):
/// returns `(sigmas (2n+1, n), Wm (2n+1), Wc (2n+1))`.
#[pyfunction]
#[pyo3(signature = (x, P, alpha, beta, kappa))]
#[allow(non_snake_case)]
fn merwe_sigma_points<'py>(
    py: Python<'py>,
    x: &Bound<'py, PyAny>,
    P: &Bound<'py, PyAny>,
    alpha: f64,
    beta: f64,
    kappa: f64,
) -> PyResult<(Arr2<'py>, Arr1<'py>, Arr1<'py>)> {
    let x = array1(x, "x", None)?;
    let (p, _, _) = array2(P, "P", Some(x.len()))?;
    let (pts, wm, wc) = sigma::merwe_sigma_points(&x, &p, alpha, beta, kappa).map_err(core_err)?;
    let n = x.len();
    Ok((matrix(py, pts, 2 * n + 1, n)?, PyArray1::from_vec(py, wm), PyArray1::from_vec(py, wc)))
}

/// Weighted mean and covariance of propagated points and their cross-covariance with the
/// points: returns `(mean_y (k), cov_y (k, k), cross (n, k))`.
#[pyfunction]
#[pyo3(signature = (sigmas_x, sigmas_y, Wm, Wc))]
#[allow(non_snake_case)]
fn unscented_transform<'py>(
    py: Python<'py>,
    sigmas_x: &Bound<'py, PyAny>,
    sigmas_y: &Bound<'py, PyAny>,
    Wm: &Bound<'py, PyAny>,
    Wc: &Bound<'py, PyAny>,
) -> PyResult<(Arr1<'py>, Arr2<'py>, Arr2<'py>)> {
    let (sx, _, n) = array2(sigmas_x, "sigmas_x", None)?;
    let (sy, _, k) = array2(sigmas_y, "sigmas_y", None)?;
    let wm = array1(Wm, "Wm", None)?;
    let wc = array1(Wc, "Wc", None)?;
    let (mean, cov, cross) = sigma::unscented_transform(&sx, n, &sy, k, &wm, &wc).map_err(core_err)?;
    Ok((PyArray1::from_vec(py, mean), matrix(py, cov, k, k)?, matrix(py, cross, n, k)?))
}

/// Damped step `(JᵀJ + λD) δ = Jᵀr` by the normal equations (`factor="normal"`) or as the least
/// squares of the augmented system (`"lstsq"`): returns `(delta, "cholesky" | "qr" | "svd")`.
#[pyfunction]
#[pyo3(signature = (J, r, lam, damping = "marquardt", factor = "normal"))]
#[allow(non_snake_case)]
fn solve_damped<'py>(
    py: Python<'py>,
    J: &Bound<'py, PyAny>,
    r: &Bound<'py, PyAny>,
    lam: f64,
    damping: &str,
    factor: &str,
) -> PyResult<(Arr1<'py>, &'static str)> {
    let damping = Damping::parse(damping).map_err(core_err)?;
    let solve = match factor {
        "normal" => solve::solve_damped,
        "lstsq" => solve::solve_damped_lstsq,
        other => {
            return Err(core_err(CoreError::InvalidParameter {
                arg: "factor",
                reason: format!("expected 'normal' or 'lstsq'; got '{other}'"),
            }));
        }
    };
    let (j, m, n) = array2(J, "J", None)?;
    let r = array1(r, "r", Some(m))?;
    let (x, how) = py.detach(|| solve(&j, &r, m, n, lam, damping)).map_err(core_err)?;
    Ok((PyArray1::from_vec(py, x), how.name()))
}

/// `J` (m, n) factored once (`J = Q·R`) for many damped steps `min ‖J·δ − b‖² + λ‖δ‖²`.
#[pyclass(name = "DampedQr", module = "robocal._robocal", frozen)]
struct PyDampedQr {
    inner: solve::DampedQr,
}

#[pymethods]
impl PyDampedQr {
    #[new]
    #[allow(non_snake_case)]
    fn new(py: Python<'_>, J: &Bound<'_, PyAny>) -> PyResult<Self> {
        let (j, m, n) = array2(J, "J", None)?;
        let inner = py.detach(|| solve::DampedQr::new(&j, m, n)).map_err(core_err)?;
        Ok(Self { inner })
    }

    /// `Qᵀb` (n,) for `b` (m,).
    fn project<'py>(&self, py: Python<'py>, b: &Bound<'py, PyAny>) -> PyResult<Arr1<'py>> {
        let b = array1(b, "b", None)?;
        let c = py.detach(|| self.inner.project(&b)).map_err(core_err)?;
        Ok(PyArray1::from_vec(py, c))
    }

    /// The damped step (n,) from `c = Qᵀb` and `lam >= 0`.
    fn solve<'py>(&self, py: Python<'py>, c: &Bound<'py, PyAny>, lam: f64) -> PyResult<Arr1<'py>> {
        let c = array1(c, "c", Some(self.inner.ncols()))?;
        let step = py.detach(|| self.inner.solve(&c, lam)).map_err(core_err)?;
        Ok(PyArray1::from_vec(py, step))
    }

    /// The triangular factor `R` (n, n) of `J = Q·R`.
    #[getter]
    fn r<'py>(&self, py: Python<'py>) -> PyResult<Arr2<'py>> {
        let n = self.inner.ncols();
        matrix(py, self.inner.r().to_vec(), n, n)
    }
}

/// `JᵀJ` (n, n) of a CSR matrix `(indptr, indices, data)` with `ncols` columns.
#[pyfunction]
fn sparse_gram<'py>(
    py: Python<'py>,
    indptr: &Bound<'py, PyAny>,
    indices: &Bound<'py, PyAny>,
    data: &Bound<'py, PyAny>,
    ncols: usize,
) -> PyResult<Arr2<'py>> {
    let indptr = index_array(indptr, "indptr")?;
    let indices = index_array(indices, "indices")?;
    let data = array1(data, "data", None)?;
    let gram = py.detach(|| solve::sparse_gram(&indptr, &indices, &data, ncols)).map_err(core_err)?;
    matrix(py, gram, ncols, ncols)
}

type Arr3<'py> = Bound<'py, PyArray3<f64>>;

/// Per fold of each labelling (`labels[s]`: a fold below `folds[s]` per row), the fold's rows'
/// `(CᵀJ (F, nc, p), Cᵀr (F, nc), CᵀC (F, nc, nc))` of the CSR matrices `C` and `J` (each
/// `(indptr, indices, data, ncols)`) and `r`.
#[pyfunction]
#[allow(non_snake_case)]
fn fold_products<'py>(
    py: Python<'py>,
    C: (Bound<'py, PyAny>, Bound<'py, PyAny>, Bound<'py, PyAny>, usize),
    J: (Bound<'py, PyAny>, Bound<'py, PyAny>, Bound<'py, PyAny>, usize),
    r: &Bound<'py, PyAny>,
    labels: Vec<Bound<'py, PyAny>>,
    folds: Vec<usize>,
) -> PyResult<Vec<(Arr3<'py>, Arr2<'py>, Arr3<'py>)>> {
    let csr = |(indptr, indices, data, ncols): &(Bound<'py, PyAny>, Bound<'py, PyAny>, Bound<'py, PyAny>, usize), arg: &'static str| {
        PyResult::Ok((index_array(indptr, "indptr")?, index_array(indices, "indices")?, array1(data, arg, None)?, *ncols))
    };
    let (c, j) = (csr(&C, "C")?, csr(&J, "J")?);
    let r = array1(r, "r", None)?;
    let labels = labels.iter().map(|l| index_array(l, "labels")).collect::<PyResult<Vec<_>>>()?;
    let products = py
        .detach(|| {
            let c = solve::Csr { indptr: &c.0, indices: &c.1, data: &c.2, ncols: c.3 };
            let j = solve::Csr { indptr: &j.0, indices: &j.1, data: &j.2, ncols: j.3 };
            solve::fold_products(c, j, &r, &labels, &folds)
        })
        .map_err(core_err)?;
    let (nc, p) = (C.3, J.3);
    products
        .into_iter()
        .zip(&folds)
        .map(|(out, &f)| {
            Ok((
                PyArray1::from_vec(py, out.ctj).reshape([f, nc, p])?,
                matrix(py, out.ctr, f, nc)?,
                PyArray1::from_vec(py, out.ctc).reshape([f, nc, nc])?,
            ))
        })
        .collect()
}

/// The CSR arrays of a Jacobian from its blocks: the dense block `dense` (m, nd) in columns
/// `dense_cols`, the thin CSR blocks (each `(indptr, indices, data, column offset)`), every data
/// row times `weights` (m,), then the rows of the CSR `extra` (`(indptr, indices, data,
/// ncols)`). Returns `(indptr, indices, data)`, the first two None unless `pattern`.
#[pyfunction]
#[allow(clippy::type_complexity)]
fn stack_csr<'py>(
    py: Python<'py>,
    dense: &Bound<'py, PyAny>,
    dense_cols: &Bound<'py, PyAny>,
    thin: Vec<(Bound<'py, PyAny>, Bound<'py, PyAny>, Bound<'py, PyAny>, usize)>,
    weights: &Bound<'py, PyAny>,
    extra: (Bound<'py, PyAny>, Bound<'py, PyAny>, Bound<'py, PyAny>, usize),
    pattern: bool,
) -> PyResult<(Option<Bound<'py, PyArray1<i64>>>, Option<Bound<'py, PyArray1<i64>>>, Arr1<'py>)> {
    let (dense, _, _) = array2(dense, "dense", None)?;
    let dense_cols = index_array(dense_cols, "dense_cols")?;
    let weights = array1(weights, "weights", None)?;
    let thin = thin
        .iter()
        .map(|(indptr, indices, data, offset)| {
            PyResult::Ok((index_array(indptr, "indptr")?, index_array(indices, "indices")?, array1(data, "thin", None)?, *offset))
        })
        .collect::<PyResult<Vec<_>>>()?;
    let extra = (index_array(&extra.0, "indptr")?, index_array(&extra.1, "indices")?, array1(&extra.2, "extra", None)?, extra.3);
    let (layout, data) = py
        .detach(|| {
            let blocks: Vec<(solve::Csr, usize)> = thin
                .iter()
                .map(|(p, i, d, offset)| (solve::Csr { indptr: p, indices: i, data: d, ncols: extra.3.saturating_sub(*offset) }, *offset))
                .collect();
            let extra = solve::Csr { indptr: &extra.0, indices: &extra.1, data: &extra.2, ncols: extra.3 };
            solve::stack_csr(&dense, &dense_cols, &blocks, &weights, extra, pattern)
        })
        .map_err(core_err)?;
    let as_i64 = |v: Vec<usize>| PyArray1::from_vec(py, v.into_iter().map(|x| x as i64).collect::<Vec<i64>>());
    let (indptr, indices) = match layout {
        Some((indptr, indices)) => (Some(as_i64(indptr)), Some(as_i64(indices))),
        None => (None, None),
    };
    Ok((indptr, indices, PyArray1::from_vec(py, data)))
}

/// The normal equations `(JᵀJ (n, n), Jᵀr (n,))` of a dense `J` (m, n) and `r` (m,).
#[pyfunction]
#[pyo3(signature = (J, r))]
#[allow(non_snake_case)]
fn normal_equations<'py>(py: Python<'py>, J: &Bound<'py, PyAny>, r: &Bound<'py, PyAny>) -> PyResult<(Arr2<'py>, Arr1<'py>)> {
    let (j, m, n) = array2(J, "J", None)?;
    let r = array1(r, "r", Some(m))?;
    let (gram, g) = py.detach(|| solve::normal_equations(&j, &r, m, n)).map_err(core_err)?;
    Ok((matrix(py, gram, n, n)?, PyArray1::from_vec(py, g)))
}

/// Identifiability of `J` (m, n): rank, singular values, identifiable subset, redundancy.
#[pyfunction]
#[pyo3(signature = (J, tol = 1e-9))]
#[allow(non_snake_case)]
fn identifiability<'py>(py: Python<'py>, J: &Bound<'py, PyAny>, tol: f64) -> PyResult<Bound<'py, PyDict>> {
    let (j, m, n) = array2(J, "J", None)?;
    let id = py.detach(|| identify::identifiability(&j, m, n, tol)).map_err(core_err)?;
    let d = PyDict::new(py);
    d.set_item("singular_values", PyArray1::from_vec(py, id.singular_values))?;
    d.set_item("rank", id.rank)?;
    d.set_item("condition_number", id.condition_number)?;
    d.set_item("column_norms", PyArray1::from_vec(py, id.column_norms))?;
    d.set_item("identifiable", id.identifiable)?;
    d.set_item("no_effect", id.no_effect)?;
    d.set_item("redundant", id.redundant)?;
    Ok(d)
}

/// Parameter covariance `σ̂²(JᵀJ)⁺`: returns `(cov (n, n), sigma2, dof, rank)`.
#[pyfunction]
#[pyo3(signature = (J, r, tol = 1e-9))]
#[allow(non_snake_case)]
fn covariance<'py>(py: Python<'py>, J: &Bound<'py, PyAny>, r: &Bound<'py, PyAny>, tol: f64) -> PyResult<(Arr2<'py>, f64, usize, usize)> {
    let (j, m, n) = array2(J, "J", None)?;
    let r = array1(r, "r", Some(m))?;
    let (cov, s2, dof, rank) = py.detach(|| identify::covariance(&j, &r, m, n, tol)).map_err(core_err)?;
    Ok((matrix(py, cov, n, n)?, s2, dof, rank))
}

/// One label per sample of `q` (m, n): samples within `tol` of each other on every joint
/// (chained) share one, numbered in order of first appearance.
#[pyfunction]
#[pyo3(signature = (q, tol))]
fn configuration_groups<'py>(py: Python<'py>, q: &Bound<'py, PyAny>, tol: f64) -> PyResult<Bound<'py, PyArray1<i64>>> {
    let (q, m, n) = array2(q, "q", None)?;
    let labels = py.detach(|| crate::configurations::configuration_groups(&q, m, n, tol)).map_err(core_err)?;
    Ok(PyArray1::from_vec(py, labels.into_iter().map(|v| v as i64).collect()))
}

/// Closed-form cable anchor and sensor zero from tool points `p` (m, 3) and lengths `L` (m):
/// returns `(anchor (3,), cable_offset)`.
#[pyfunction]
#[pyo3(signature = (p, L))]
#[allow(non_snake_case)]
fn cable_initial_guess<'py>(py: Python<'py>, p: &Bound<'py, PyAny>, L: &Bound<'py, PyAny>) -> PyResult<(Arr1<'py>, f64)> {
    let (p, m, _) = array2(p, "p", Some(3))?;
    let l = array1(L, "L", Some(m))?;
    let (anchor, offset) = measurement::cable_initial_guess(&p, &l).map_err(core_err)?;
    Ok((PyArray1::from_vec(py, anchor.to_vec()), offset))
}

#[pymodule]
fn _robocal(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyChain>()?;
    m.add_function(wrap_pyfunction!(merwe_sigma_points, m)?)?;
    m.add_function(wrap_pyfunction!(unscented_transform, m)?)?;
    m.add_function(wrap_pyfunction!(solve_damped, m)?)?;
    m.add_class::<PyDampedQr>()?;
    m.add_function(wrap_pyfunction!(sparse_gram, m)?)?;
    m.add_function(wrap_pyfunction!(fold_products, m)?)?;
    m.add_function(wrap_pyfunction!(stack_csr, m)?)?;
    m.add_function(wrap_pyfunction!(configuration_groups, m)?)?;
    m.add_function(wrap_pyfunction!(normal_equations, m)?)?;
    // The core parallelises over samples (rayon); faer's own threads only add hand-over cost to
    // its small dense factorisations (a pivoted QR of 1600×24 had gone 0.41 → 0.33 ms without them).
    faer::set_global_parallelism(faer::Par::Seq);
    m.add_function(wrap_pyfunction!(identifiability, m)?)?;
    m.add_function(wrap_pyfunction!(covariance, m)?)?;
    m.add_function(wrap_pyfunction!(cable_initial_guess, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
