//! Writing Parquet: the table writers ([`table`], Arrow batches or whole row groups of
//! plain vectors), the encoders ingest applies itself ([`encoding`]), row groups cut at
//! session boundaries (`rowgroup`), and the raw streams' writer (`streams`).

pub mod encoding;
pub(crate) mod rowgroup;
pub(crate) mod streams;
pub mod table;
