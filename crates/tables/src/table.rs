//! What the walk tables share: the JSON files they are stored in and the checks that reject a
//! damaged one ([`TableFile`], [`TableError`]), the per-process cache of tables simulated for
//! media other than the shipped one ([`for_medium`]), and the spline over the albedo grid that
//! every table's rows are looked up with ([`albedo_spline`]).

use crate::exit::{ExitTableSettings, ONE_MINUS_ALBEDO};

/// The tables simulated at run time for media other than the shipped one, per process.
pub(crate) type MediumCache<T> = std::sync::Mutex<Vec<std::sync::Arc<T>>>;

/// Errors of reading a table ([`TableFile::from_json`]); each names the file and the field.
#[derive(Debug, thiserror::Error)]
pub enum TableError {
    /// The text is not the JSON of this kind of table.
    #[error(
        "{name}: not a valid {table} table ({reason}); fix: regenerate it with `translucent model {table}-table`"
    )]
    Parse {
        /// The file.
        name: String,
        /// The kind of table (`exit`, `incidence`, `curvature`).
        table: &'static str,
        /// What the JSON parser said.
        reason: String,
    },
    /// A field has the wrong length or an impossible value.
    #[error(
        "{name}: {table} table field `{field}` {reason}; fix: regenerate it with `translucent model {table}-table`"
    )]
    Invalid {
        /// The file.
        name: String,
        /// The kind of table.
        table: &'static str,
        /// The field (`settings.g`, `a`, `a[17]`, …).
        field: String,
        /// What is wrong with it.
        reason: String,
    },
}

/// A table stored as JSON (the shipped `data/*.json` files, written by `translucent model
/// …-table`): parsed, then checked against the grid of this build, so that a damaged or
/// mismatched file is an error naming the field and never an out-of-bounds lookup later.
pub trait TableFile: serde::de::DeserializeOwned {
    /// The kind of table, as in the command that writes it (`exit`, `incidence`, `curvature`).
    const KIND: &'static str;

    /// Checks lengths and values; `name` is the file, for the error.
    fn check(&self, name: &str) -> Result<(), TableError>;

    /// Parses and checks the JSON text of a table; `name` is the file, for errors.
    fn from_json(text: &str, name: &str) -> Result<Self, TableError> {
        let table: Self = serde_json::from_str(text).map_err(|e| TableError::Parse {
            name: name.to_string(),
            table: Self::KIND,
            reason: e.to_string(),
        })?;
        table.check(name)?;
        Ok(table)
    }
}

/// Checks shared by the table files: lengths against the grid, values finite and in range.
pub(crate) struct TableCheck<'a> {
    pub(crate) name: &'a str,
    pub(crate) table: &'static str,
}

impl TableCheck<'_> {
    pub(crate) fn err(&self, field: impl Into<String>, reason: impl Into<String>) -> TableError {
        TableError::Invalid {
            name: self.name.to_string(),
            table: self.table,
            field: field.into(),
            reason: reason.into(),
        }
    }

    /// `len == expected`.
    pub(crate) fn len(&self, field: &str, len: usize, expected: usize) -> Result<(), TableError> {
        if len != expected {
            return Err(self.err(
                field,
                format!("holds {len} values, this build's grid needs {expected}"),
            ));
        }
        Ok(())
    }

    /// Every value finite and within `[lo, hi]`.
    pub(crate) fn values(
        &self,
        field: &str,
        v: &[f32],
        lo: f32,
        hi: f32,
    ) -> Result<(), TableError> {
        if let Some(i) = v
            .iter()
            .position(|x| !(x.is_finite() && (lo..=hi).contains(x)))
        {
            return Err(self.err(
                format!("{field}[{i}]"),
                format!("= {} is outside [{lo}, {hi}]", v[i]),
            ));
        }
        Ok(())
    }

    /// The medium of a walk table: |g| < 1, η finite and positive.
    pub(crate) fn settings(&self, s: &ExitTableSettings) -> Result<(), TableError> {
        if !(s.g.is_finite() && s.g.abs() < 1.0) {
            return Err(self.err("settings.g", format!("= {} is outside (-1, 1)", s.g)));
        }
        if !(s.eta.is_finite() && s.eta > 0.0) {
            return Err(self.err("settings.eta", format!("= {} is not positive", s.eta)));
        }
        if !(0.0..=1.0).contains(&s.roughness) {
            return Err(self.err(
                "settings.roughness",
                format!("= {} is outside [0, 1]", s.roughness),
            ));
        }
        Ok(())
    }
}

/// A shipped table (JSON built into the binary, `name` its file under `data/`), parsed and
/// checked once.
pub(crate) fn shipped<T: TableFile>(
    cell: &std::sync::OnceLock<std::sync::Arc<T>>,
    json: &str,
    name: &str,
) -> std::sync::Arc<T> {
    cell.get_or_init(|| {
        std::sync::Arc::new(
            T::from_json(json, name)
                .unwrap_or_else(|e| panic!("a shipped table reads (checked by its tests): {e}")),
        )
    })
    .clone()
}

/// A table simulated by half-space walks with [`ExitTableSettings`] (the exit and incidence
/// tables), so that [`for_medium`] can make and look up the table of any medium.
pub(crate) trait WalkTable: TableFile + serde::Serialize {
    /// The settings the table was made with.
    fn settings(&self) -> &ExitTableSettings;
    /// Simulate the table.
    fn simulate(settings: ExitTableSettings) -> Self;
}

/// The table of a medium `(g, η, roughness)`: `shipped` when its own match, else one simulated
/// with `walks` walks per row (seed 0) once per process and kept in `cache` (and on disk for
/// the next process, [`crate::disk`]).
pub(crate) fn for_medium<T: WalkTable>(
    cache: &MediumCache<T>,
    shipped: std::sync::Arc<T>,
    (g, eta, roughness): (f32, f32, f32),
    walks: u32,
) -> std::sync::Arc<T> {
    let key = |t: &T| (t.settings().g, t.settings().eta, t.settings().roughness);
    if key(&shipped) == (g, eta, roughness) {
        return shipped;
    }
    let mut cache = cache.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(t) = cache.iter().find(|t| key(t) == (g, eta, roughness)) {
        return t.clone();
    }
    let settings = ExitTableSettings {
        g,
        eta,
        roughness,
        walks,
        seed: 0,
    };
    let t = std::sync::Arc::new(crate::disk::load_or_simulate::<T>(
        crate::disk::folder().as_deref(),
        settings,
    ));
    cache.push(t.clone());
    t
}

/// A table of rows over the albedo grid [`ONE_MINUS_ALBEDO`] (`rows[a·n..(a + 1)·n]` for grid
/// albedo a) at albedo `albedo`, with its α-derivative: a cubic Hermite spline in
/// x = ln(1 − α) through the grid albedos (tangents by central differences, one-sided at the
/// ends; C¹, so the derivative is continuous), constant outside the grid (derivative 0). The
/// spline is a linear combination of rows, so any linear normalisation of the rows holds for
/// every albedo.
pub(crate) fn albedo_spline(rows: &[f32], n: usize, albedo: f32) -> (Vec<f32>, Vec<f32>) {
    let xs: Vec<f32> = ONE_MINUS_ALBEDO.iter().map(|x| x.ln()).collect();
    let x = (1.0 - albedo).clamp(1e-6, 1.0).ln();
    let last = xs.len() - 1;
    let row = |a: usize| &rows[a * n..(a + 1) * n];
    // Outside the grid (xs decreases with a): the end row, no α-dependence.
    let end = if x >= xs[0] {
        Some(0)
    } else if x <= xs[last] {
        Some(last)
    } else {
        None
    };
    if let Some(a) = end {
        return (row(a).to_vec(), vec![0.0; n]);
    }
    let a = (0..last)
        .find(|&a| x <= xs[a] && x >= xs[a + 1])
        .unwrap_or(0);
    let h = xs[a + 1] - xs[a]; // < 0
    let t = (x - xs[a]) / h;
    // Tangent dF/dx at node k for cell value index `i`.
    let tangent = |k: usize, i: usize| {
        let (lo, hi) = (k.saturating_sub(1), (k + 1).min(last));
        (row(hi)[i] - row(lo)[i]) / (xs[hi] - xs[lo])
    };
    let (t2, t3) = (t * t, t * t * t);
    let (h00, h10, h01, h11) = (
        2.0 * t3 - 3.0 * t2 + 1.0,
        t3 - 2.0 * t2 + t,
        -2.0 * t3 + 3.0 * t2,
        t3 - t2,
    );
    let (d00, d10, d01, d11) = (
        6.0 * t2 - 6.0 * t,
        3.0 * t2 - 4.0 * t + 1.0,
        -6.0 * t2 + 6.0 * t,
        3.0 * t2 - 2.0 * t,
    );
    // dx/dα = −1/(1 − α); dt/dx = 1/h.
    let dt_da = -1.0 / ((1.0 - albedo).max(1e-6) * h);
    let (r0, r1) = (row(a), row(a + 1));
    let mut f = Vec::with_capacity(n);
    let mut df = Vec::with_capacity(n);
    for i in 0..n {
        let (m0, m1) = (tangent(a, i) * h, tangent(a + 1, i) * h);
        f.push(h00 * r0[i] + h10 * m0 + h01 * r1[i] + h11 * m1);
        df.push((d00 * r0[i] + d10 * m0 + d01 * r1[i] + d11 * m1) * dt_da);
    }
    (f, df)
}

/// Walks per row of a table simulated at run time (the shipped one has more).
pub const DEFAULT_RUNTIME_WALKS: u32 = 40_000;
