//! The ingest stage's error type: bad input (named by file, line or byte offset, and field)
//! kept apart from I/O failures and bugs.

use std::path::PathBuf;

/// What can go wrong while ingesting a dataset.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// The manifest is not valid: `key` names the offending key (e.g. `session[1].date`).
    #[error("{}: {key}: {message}", path.display())]
    Manifest {
        /// The manifest file.
        path: PathBuf,
        /// The key, as a path into the manifest.
        key: String,
        /// What is wrong with it.
        message: String,
    },
    /// A line of a text log does not parse.
    #[error("{}:{line}: {field}: {message}", path.display())]
    Line {
        /// The log file.
        path: PathBuf,
        /// 1-based line number.
        line: u64,
        /// The field (column name) that is wrong, or `line` for the whole line.
        field: String,
        /// What is wrong with it.
        message: String,
    },
    /// A file could not be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// Writing or opening a Parquet table failed.
    #[error("{}: {source}", path.display())]
    Parquet {
        /// The table being written.
        path: PathBuf,
        /// The underlying error.
        source: parquet::errors::ParquetError,
    },
    /// The run wrote its outputs, but some session is unusable as a whole (no data, a sample
    /// rate off the declared one): the ledger `path` lists why.
    #[error("{}: {}", path.display(), errors.join("; "))]
    Unusable {
        /// The ledger that records the errors.
        path: PathBuf,
        /// One message per problem, naming the session and file.
        errors: Vec<String>,
    },
    /// An upstream file is not the one its stage recorded (changed, missing, or from another
    /// dataset): the message names the command to re-run.
    #[error("{}: {message}", path.display())]
    Stale {
        /// The file.
        path: PathBuf,
        /// What differs and what to re-run.
        message: String,
    },
    /// A table does not read as its schema in `contract::tables` says (a column missing or
    /// of another type, an unknown unit, a batch that does not decode).
    #[error("{}: {message}", path.display())]
    Table {
        /// The table's file.
        path: PathBuf,
        /// What is wrong with it.
        message: String,
    },
    /// Building an Arrow batch failed (a bug: the batches are built to their schema).
    #[error("building an Arrow batch for {}: {source}", path.display())]
    Arrow {
        /// The table's file.
        path: PathBuf,
        /// The underlying error.
        source: arrow_schema::ArrowError,
    },
}

impl Error {
    /// A file `path` could not be read or written: every stage's I/O error.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }
}

/// Result with this crate's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;
