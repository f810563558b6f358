//! Errors as Python exceptions: every refusal of the libraries (a description's
//! `file:line` problems, a bad design named by field, a corrupt model) becomes
//! `pino_mbd.PinoError`, a `ValueError`, carrying the same message as the command line.

use pyo3::create_exception;
use pyo3::exceptions::PyValueError;
use pyo3::PyErr;

create_exception!(
    _pino_mbd,
    PinoError,
    PyValueError,
    "A refusal of pino-mbd: bad input named by file, line and field (a ValueError)."
);

/// `message` as a [`PinoError`].
pub fn value_error(message: impl Into<String>) -> PyErr {
    PinoError::new_err(message.into())
}

/// Any library error, by its message (`{e:#}` keeps the whole context chain).
pub fn to_py(e: impl std::fmt::Display) -> PyErr {
    value_error(format!("{e:#}"))
}
