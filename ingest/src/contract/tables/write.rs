//! How the stream tables are written, a row group at a time: each table declares its row
//! group as a struct with a field per column ([`RowGroup`]), so that a stage sets every
//! column by its name, a column left out does not compile, and only the table's own module
//! says which field goes under which name, in the schema's order. The writer
//! ([`GroupWriter`]) takes nothing else; [`ColumnTableWriter`] then checks those names
//! against the schema's, so a list that slipped is refused, never written.

use crate::error::Result;
use crate::parquet_io::table::{ColumnTableWriter, ColumnValues, Written, unnamed};
use std::marker::PhantomData;

/// A row group of one table, a field per column.
pub trait RowGroup {
    /// How the table names its columns (`&'static str`, or `String` where the names follow
    /// from the data, as the applied table's accelerometers).
    type Name: AsRef<str> + Sync;
    /// The rows the group holds.
    fn rows(&self) -> usize;
    /// The columns, each under its name, in the schema's order.
    fn named(self) -> Vec<(Self::Name, ColumnValues)>;
}

/// A table being written a row group at a time, from row groups of its own type `G` only.
pub struct GroupWriter<G> {
    table: ColumnTableWriter,
    group: PhantomData<fn(G)>,
}

impl<G: RowGroup> GroupWriter<G> {
    /// Wraps `table`, created by the table's module with its file, schema and encodings.
    pub(super) fn new(table: ColumnTableWriter) -> Self {
        GroupWriter {
            table,
            group: PhantomData,
        }
    }

    /// Writes one row group (none where it holds no rows); returns its columns' buffers,
    /// for the next row groups.
    pub fn write(&mut self, group: G) -> Result<Vec<ColumnValues>> {
        let rows = group.rows();
        let columns = group.named();
        self.table.write_row_group(rows, &columns)?;
        Ok(unnamed(columns))
    }

    /// Closes the table and renames it into place; returns its rows and SHA-256 (hashed as
    /// it was written).
    pub fn finish_hashed(self) -> Result<Written> {
        self.table.finish_hashed()
    }
}

/// A nullable column as it is written: the values that are not null, and the definition
/// levels of all rows (1 valued, 0 null), none where no value is null.
pub type Nullable<T> = (Vec<T>, Option<Vec<i16>>);
