//! Library errors as Python exceptions, with the library's message and its causes (the CLI's
//! `error: …` line).
//!
//! | library error | Python exception |
//! |---|---|
//! | a value that cannot be used (`SceneError::Invalid`, `RecoveryError::Invalid`, `InverseError::Invalid`) | `ValueError` |
//! | a file that exists and may not be replaced (`SceneError::Exists`) | `FileExistsError` |
//! | a file that cannot be read or written (`SceneError::Io`) | `OSError` |
//! | anything else | `translucent.Error` |

use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyFileExistsError, PyOSError, PyValueError};
use pyo3::prelude::*;

create_exception!(
    translucent,
    Error,
    PyException,
    "An error of translucent: a render, a recovery or a file that failed (the message says what \
     and how to fix it)."
);

/// The message and each cause, as `a: b: c` (anyhow's `{:#}`).
pub fn chain(e: &(dyn std::error::Error + 'static)) -> String {
    let mut s = e.to_string();
    let mut cause = e.source();
    while let Some(c) = cause {
        let m = c.to_string();
        if !s.contains(&m) {
            s.push_str(": ");
            s.push_str(&m);
        }
        cause = c.source();
    }
    s
}

/// A scene error (reading or checking a file, a medium, a dataset).
pub fn scene(e: scene::SceneError) -> PyErr {
    use scene::SceneError as E;
    let m = chain(&e);
    match e {
        E::Invalid { .. } | E::Parse { .. } | E::Geometry(_) => PyValueError::new_err(m),
        E::Exists { .. } => PyFileExistsError::new_err(m),
        E::Io { .. } => PyOSError::new_err(m),
        _ => Error::new_err(m),
    }
}

/// An error of the inverse core (a render).
pub fn inverse(e: inverse::optimize::InverseError) -> PyErr {
    use inverse::optimize::InverseError as E;
    match e {
        E::Write(s) => scene(s),
        E::Invalid(m) => PyValueError::new_err(m),
        e => Error::new_err(chain(&e)),
    }
}

/// An error of a recovery.
pub fn recovery(e: recovery::RecoveryError) -> PyErr {
    use recovery::RecoveryError as E;
    match e {
        E::Invalid(m) => PyValueError::new_err(m),
        E::Scene(s) => scene(s),
        E::Inverse(i) => inverse(i),
        e => Error::new_err(chain(&e)),
    }
}

/// A learned model that could not be loaded.
pub fn model(e: bssrdf::model::ModelError) -> PyErr {
    Error::new_err(chain(&e))
}
