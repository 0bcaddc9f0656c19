//! NumPy inputs to owned buffers with argument-naming errors, and `CoreError` to
//! `robocal.exceptions`.

use crate::error::CoreError;
use numpy::{PyReadonlyArray1, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::prelude::*;

/// Raises `robocal.exceptions.<class>(message)`.
fn robocal_error(class: &str, message: String) -> PyErr {
    Python::attach(|py| {
        let made = py.import("robocal.exceptions").and_then(|m| m.getattr(class)).and_then(|cls| cls.call1((message,)));
        match made {
            Ok(instance) => PyErr::from_value(instance),
            Err(e) => e,
        }
    })
}

/// One Python exception class per `CoreError` variant.
pub fn core_err(e: CoreError) -> PyErr {
    let class = match &e {
        CoreError::Shape { .. } => "ShapeError",
        CoreError::NonFinite { .. } => "NonFiniteError",
        CoreError::InvalidParameter { .. } | CoreError::OutOfRange { .. } => "InvalidParameterError",
        CoreError::Singular(_) => "SingularError",
        CoreError::NotPositiveDefinite(_) => "NotPositiveDefiniteError",
        CoreError::NoConvergence(_) => "NoConvergenceError",
    };
    robocal_error(class, e.to_string())
}

fn describe(obj: &Bound<'_, PyAny>) -> String {
    match obj.getattr("dtype") {
        Ok(dtype) => format!("an array of dtype {dtype}"),
        Err(_) => format!("a {}", obj.get_type().name().map(|n| n.to_string()).unwrap_or_else(|_| "?".into())),
    }
}

fn shape_str(shape: &[usize]) -> String {
    let parts: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
    if parts.len() == 1 {
        format!("({},)", parts[0])
    } else {
        format!("({})", parts.join(", "))
    }
}

/// A float64 array of any layout, copied in logical (C) order, with its shape.
fn owned(obj: &Bound<'_, PyAny>, arg: &'static str) -> PyResult<(Vec<f64>, Vec<usize>)> {
    let arr: PyReadonlyArrayDyn<'_, f64> = obj.extract().map_err(|_| {
        core_err(CoreError::InvalidParameter { arg, reason: format!("must be a float64 NumPy array; got {}", describe(obj)) })
    })?;
    let shape = arr.shape().to_vec();
    // `as_slice` also succeeds on Fortran-ordered arrays (memory order); only a C-ordered
    // buffer may be copied as is, anything else is copied in logical order.
    let data = match arr.as_slice() {
        Ok(s) if arr.is_c_contiguous() => s.to_vec(),
        _ => arr.as_array().iter().copied().collect(),
    };
    Ok((data, shape))
}

/// A 1-D float64 array (length checked when `len` is given).
pub fn array1(obj: &Bound<'_, PyAny>, arg: &'static str, len: Option<usize>) -> PyResult<Vec<f64>> {
    let (data, shape) = owned(obj, arg)?;
    if shape.len() != 1 || len.is_some_and(|n| shape[0] != n) {
        let expected = len.map_or("(n,)".to_string(), |n| format!("({n},)"));
        return Err(core_err(CoreError::Shape { arg, expected, got: shape_str(&shape) }));
    }
    Ok(data)
}

/// A 2-D float64 array (column count checked when `ncols` is given): `(data, rows, cols)`.
pub fn array2(obj: &Bound<'_, PyAny>, arg: &'static str, ncols: Option<usize>) -> PyResult<(Vec<f64>, usize, usize)> {
    let (data, shape) = owned(obj, arg)?;
    if shape.len() != 2 || ncols.is_some_and(|n| shape[1] != n) {
        let expected = ncols.map_or("(m, n)".to_string(), |n| format!("(m, {n})"));
        return Err(core_err(CoreError::Shape { arg, expected, got: shape_str(&shape) }));
    }
    Ok((data, shape[0], shape[1]))
}

/// A sequence of non-negative integers (list or integer array).
pub fn index_list(obj: &Bound<'_, PyAny>, arg: &'static str) -> PyResult<Vec<usize>> {
    let values: Vec<i64> = obj.extract().map_err(|_| {
        core_err(CoreError::InvalidParameter { arg, reason: format!("must be a sequence of integers; got {}", describe(obj)) })
    })?;
    values
        .into_iter()
        .map(|v| {
            usize::try_from(v).map_err(|_| core_err(CoreError::InvalidParameter { arg, reason: format!("indices must be >= 0; got {v}") }))
        })
        .collect()
}

/// A 1-D integer array of non-negative values (int64 or int32, as scipy.sparse stores indices).
pub fn index_array(obj: &Bound<'_, PyAny>, arg: &'static str) -> PyResult<Vec<usize>> {
    let values: Vec<i64> = if let Ok(a) = obj.extract::<PyReadonlyArray1<'_, i64>>() {
        a.as_array().to_vec()
    } else if let Ok(a) = obj.extract::<PyReadonlyArray1<'_, i32>>() {
        a.as_array().iter().map(|&v| v as i64).collect()
    } else {
        return Err(core_err(CoreError::InvalidParameter {
            arg,
            reason: format!("must be a 1-D int32 or int64 NumPy array; got {}", describe(obj)),
        }));
    };
    values
        .into_iter()
        .map(|v| {
            usize::try_from(v).map_err(|_| core_err(CoreError::InvalidParameter { arg, reason: format!("indices must be >= 0; got {v}") }))
        })
        .collect()
}
