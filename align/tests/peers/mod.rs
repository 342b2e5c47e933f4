//! The Python peers' interpreter, for the tests that run a peer side by side: the virtual
//! environment `.ci/peers-venv.sh` makes, or `GRAVCAL_PEERS_PYTHON`; `GRAVCAL_SKIP_PEERS=1`
//! leaves such a test out and says so.

use std::path::PathBuf;

/// The interpreter, or None when the user asked to skip the peers.
pub fn peers_python() -> Option<PathBuf> {
    if std::env::var("GRAVCAL_SKIP_PEERS").as_deref() == Ok("1") {
        eprintln!("GRAVCAL_SKIP_PEERS=1: no comparison with the Python peers");
        return None;
    }
    let py = std::env::var_os("GRAVCAL_PEERS_PYTHON").map_or_else(
        || PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target/peers-venv/bin/python"),
        PathBuf::from,
    );
    assert!(
        py.exists(),
        "no peers' Python at {}: run `bash .ci/peers-venv.sh` (or set GRAVCAL_SKIP_PEERS=1)",
        py.display()
    );
    Some(py)
}
