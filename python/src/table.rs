//! Tables handed to Python: named columns and the rows' values as little-endian `f64`
//! bytes, which `numpy.frombuffer` reads without a copy per element.

use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict};

/// A table of `f64` with named columns, row-major.
pub struct Table {
    columns: Vec<&'static str>,
    data: Vec<u8>,
    rows: usize,
}

impl Table {
    /// An empty table with these columns.
    pub fn new(columns: &[&'static str]) -> Self {
        Table {
            columns: columns.to_vec(),
            data: Vec::new(),
            rows: 0,
        }
    }

    /// Append a row; its length must be the number of columns.
    pub fn push(&mut self, row: impl IntoIterator<Item = f64>) {
        let before = self.data.len();
        for v in row {
            self.data.extend_from_slice(&v.to_le_bytes());
        }
        debug_assert_eq!(self.data.len() - before, 8 * self.columns.len());
        self.rows += 1;
    }

    /// `{"columns": [...], "rows": n, "data": bytes}`.
    pub fn into_py(self, py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
        let d = PyDict::new(py);
        d.set_item("columns", self.columns)?;
        d.set_item("rows", self.rows)?;
        d.set_item("data", PyBytes::new(py, &self.data))?;
        Ok(d)
    }
}
