//! How the tables are written a row group at a time: each table declares its row group as a
//! struct with a field per column ([`RowGroup`]), so that a stage sets every column by its
//! name and a column left out does not compile; only the table's own module says which
//! field stands under which name, in the schema's order. The writer ([`GroupWriter`]) takes
//! row groups of its table's type only; [`ColumnTableWriter`] then checks those names
//! against the schema's, so a list that slipped is refused, never written.

use super::{SESSION_INDEX, SchemaRef, TIME_GPS_NS};
use crate::error::Result;
use crate::parquet_io::table::{
    ColumnTableWriter, ColumnValues, Encodings, INGEST_GROUPS_PER_SYNC, Written, unnamed,
};
use std::path::Path;

/// A row group of one table, a field per column.
pub trait RowGroup {
    /// How the table names its columns (`&'static str`, or `String` where the names follow
    /// from the data, as the applied table's accelerometers).
    type Name: AsRef<str> + Sync;
    /// What the writer knows of the names that the row group does not carry.
    type Names: Send;
    /// The rows the group holds.
    fn rows(&self) -> usize;
    /// The columns, each under its name, in the schema's order.
    fn named(self, names: &Self::Names) -> Vec<(Self::Name, ColumnValues)>;
}

/// A nullable column as it is written: the values that are not null, and the definition
/// levels of all rows (1 valued, 0 null), none where no value is null.
pub type Nullable<T> = (Vec<T>, Option<Vec<i16>>);

/// A table being written a row group at a time, from row groups of its own type `G` only.
pub struct GroupWriter<G: RowGroup> {
    table: ColumnTableWriter,
    names: G::Names,
}

impl<G: RowGroup> GroupWriter<G> {
    /// Wraps `table`, created by the table's module with its file, schema and encodings.
    pub(super) fn new(table: ColumnTableWriter, names: G::Names) -> Self {
        GroupWriter { table, names }
    }

    /// Writes one row group (none where it holds no rows); returns its columns' buffers,
    /// for the next row groups.
    pub fn write(&mut self, group: G) -> Result<Vec<ColumnValues>> {
        let rows = group.rows();
        let columns = group.named(&self.names);
        self.table.write_row_group(rows, &columns)?;
        Ok(unnamed(columns))
    }

    /// Closes the table and renames it into place; returns its rows and SHA-256 (hashed as
    /// it was written).
    pub fn finish_hashed(self) -> Result<Written> {
        self.table.finish_hashed()
    }
}

/// A value type as Parquet stores it.
pub trait Stored: Sized {
    /// A column of these values.
    fn column(values: Vec<Self>, levels: Option<Vec<i16>>) -> ColumnValues;
}

impl Stored for i32 {
    fn column(values: Vec<i32>, levels: Option<Vec<i16>>) -> ColumnValues {
        ColumnValues::Int32(values, levels)
    }
}

impl Stored for i64 {
    fn column(values: Vec<i64>, levels: Option<Vec<i16>>) -> ColumnValues {
        ColumnValues::Int64(values, levels)
    }
}

impl Stored for f64 {
    fn column(values: Vec<f64>, levels: Option<Vec<i16>>) -> ColumnValues {
        ColumnValues::Double(values, levels)
    }
}

/// A row group of a sample stream's table (acceleration, temperature, lab): the session
/// index, the GPS time, channels 1..3 of values `V` and the stream's last column of `L`
/// (the status bits, or the line). The channels' and the last column's names are the
/// table's, which its writer holds ([`stream_writer`]).
pub struct StreamRows<V, L> {
    /// Session index per row (UInt16, stored as INT32).
    pub session_index: Vec<i32>,
    /// GPS time per row, ns.
    pub time_gps_ns: Vec<i64>,
    /// Channels 1..3, each null where the sample gave no value.
    pub channels: [Nullable<V>; 3],
    /// The last column.
    pub last: Vec<L>,
}

/// A sample stream's names: its channels' and its last column's.
pub type StreamNames = ([&'static str; 3], &'static str);

impl<V: Stored, L: Stored> RowGroup for StreamRows<V, L> {
    type Name = &'static str;
    type Names = StreamNames;
    fn rows(&self) -> usize {
        self.time_gps_ns.len()
    }
    fn named(self, (channels, last): &StreamNames) -> Vec<(&'static str, ColumnValues)> {
        let mut named = vec![
            (SESSION_INDEX, ColumnValues::Int32(self.session_index, None)),
            (TIME_GPS_NS, ColumnValues::Int64(self.time_gps_ns, None)),
        ];
        for (name, (values, levels)) in channels.iter().zip(self.channels) {
            named.push((name, V::column(values, levels)));
        }
        named.push((last, L::column(self.last, None)));
        named
    }
}

/// A sample stream's table (acceleration, temperature, lab) started in `dir` as ingest
/// writes them: one column after another on the writer's thread, synced every few row
/// groups.
pub(super) fn stream_writer<V: Stored, L: Stored>(
    dir: &Path,
    (file, schema, names): (&str, SchemaRef, StreamNames),
    encodings: Encodings<'_>,
) -> Result<GroupWriter<StreamRows<V, L>>> {
    let table = ColumnTableWriter::create(dir, file, schema, encodings)?
        .one_column_at_a_time()
        .sync_every(INGEST_GROUPS_PER_SYNC);
    Ok(GroupWriter::new(table, names))
}
