//! Tables across the language boundary through the Arrow C stream interface (the
//! `__arrow_c_stream__` PyCapsule protocol that polars, pandas and pyarrow speak): a result
//! leaves as an [`ArrowTable`] whose buffers are the library's own vectors (no copy on either
//! side), and a table given by the caller (designs, profiles) is read from its stream.

use crate::error::value_error;
use arrow_array::ffi_stream::{FFI_ArrowArrayStream, RecordBatchStreamReader};
use arrow_array::{RecordBatch, RecordBatchIterator};
use pino_data::Table;
use pyo3::prelude::*;
use pyo3::types::PyCapsule;
use std::ffi::CString;
use std::path::Path;

/// The capsule name the protocol requires.
const STREAM: &std::ffi::CStr = c"arrow_array_stream";

/// A result table, handed to polars, pandas or pyarrow as an Arrow stream of one batch; each
/// field carries its unit (`unit` field metadata).
#[pyclass(module = "pino_mbd._pino_mbd", frozen)]
pub struct ArrowTable {
    batch: RecordBatch,
}

impl ArrowTable {
    /// `table` moved into Arrow buffers (every column with the unit the table carries or the
    /// fixed table's, or an error naming the column; `what` names the table).
    pub fn new(table: Table, what: &str) -> PyResult<Self> {
        let batch = pino_data::batch::into_record_batch(table, Path::new(what))
            .map_err(|e| value_error(e.to_string()))?;
        Ok(Self { batch })
    }
}

#[pymethods]
impl ArrowTable {
    /// The Arrow C stream of the table (the PyCapsule protocol; the requested schema is
    /// ignored: the table has one).
    #[pyo3(signature = (requested_schema=None))]
    fn __arrow_c_stream__<'py>(
        &self,
        py: Python<'py>,
        requested_schema: Option<Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyCapsule>> {
        let _ = requested_schema;
        let reader = RecordBatchIterator::new([Ok(self.batch.clone())], self.batch.schema());
        let stream = FFI_ArrowArrayStream::new(Box::new(reader));
        PyCapsule::new(py, stream, Some(CString::from(STREAM)))
    }

    /// Number of rows.
    #[getter]
    fn num_rows(&self) -> usize {
        self.batch.num_rows()
    }

    /// `{column: unit}` of every column.
    #[getter]
    fn units(&self) -> Vec<(String, String)> {
        self.batch
            .schema()
            .fields()
            .iter()
            .map(|f| {
                let unit = f.metadata().get("unit").cloned().unwrap_or_default();
                (f.name().clone(), unit)
            })
            .collect()
    }
}

/// The table `obj` exports through `__arrow_c_stream__` (floats, integers and Booleans
/// without nulls, strings with or without), `what` naming it in errors.
pub fn import(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Table> {
    if !obj.hasattr("__arrow_c_stream__")? {
        return Err(value_error(format!(
            "{what}: expected a table (polars or pandas DataFrame, pyarrow Table, dict of arrays), got {}",
            obj.get_type().name()?
        )));
    }
    let capsule = obj.call_method0("__arrow_c_stream__")?;
    let capsule = capsule.cast::<PyCapsule>().map_err(PyErr::from)?;
    let ptr = capsule.pointer_checked(Some(STREAM))?;
    // SAFETY: the capsule holds an `ArrowArrayStream` (checked by its name, as the protocol
    // requires); `from_raw` moves it out and marks the original released, so the capsule's
    // own destructor does not release it again.
    let stream = unsafe { FFI_ArrowArrayStream::from_raw(ptr.as_ptr().cast()) };
    let reader = RecordBatchStreamReader::try_new(stream)
        .map_err(|e| value_error(format!("{what}: Arrow stream: {e}")))?;
    let schema = arrow_array::RecordBatchReader::schema(&reader);
    let batches: Vec<RecordBatch> = reader
        .collect::<Result<_, _>>()
        .map_err(|e| value_error(format!("{what}: Arrow stream: {e}")))?;
    pino_data::batch::from_record_batches(&schema, &batches, Path::new(what))
        .map_err(|e| value_error(e.to_string()))
}
