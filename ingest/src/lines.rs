//! Streaming line reader shared by the text logs: reads a file in large chunks, hashes and
//! counts its bytes on the way, and hands out lines with their numbers.

use crate::error::{Error, Result};
use sha2::{Digest, Sha256};
use std::io::Read;
use std::path::Path;

const CHUNK: usize = 1 << 20;

/// Reads `path` in chunks, feeding every chunk to `on_chunk` (hashing, progress); returns the
/// SHA-256 (hex) and the size.
pub fn read_chunks(
    path: &Path,
    mut on_chunk: impl FnMut(&[u8]) -> Result<()>,
) -> Result<(String, u64)> {
    let mut f = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut hasher = Sha256::new();
    let mut buf = vec![0u8; CHUNK];
    let mut total = 0u64;
    loop {
        let n = match f.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(Error::io(path, e)),
        };
        hasher.update(&buf[..n]);
        total += n as u64;
        on_chunk(&buf[..n])?;
    }
    let digest = hasher.finalize();
    let hex = digest
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect::<String>();
    Ok((hex, total))
}

/// Calls `on_line(number, line)` for every line of `path` (without `\n` or `\r\n`; 1-based
/// numbers); returns the SHA-256 and size.
pub fn read_lines(
    path: &Path,
    progress: &indicatif::ProgressBar,
    mut on_line: impl FnMut(u64, &[u8]) -> Result<()>,
) -> Result<(String, u64)> {
    let mut carry: Vec<u8> = Vec::new();
    let mut number = 0u64;
    let mut emit = |number: &mut u64, line: &[u8]| {
        *number += 1;
        let line = line.strip_suffix(b"\r").unwrap_or(line);
        on_line(*number, line)
    };
    let (hash, bytes) = read_chunks(path, |chunk| {
        progress.inc(chunk.len() as u64);
        let mut start = 0;
        let mut it = chunk
            .iter()
            .enumerate()
            .filter(|(_, b)| **b == b'\n')
            .map(|(i, _)| i);
        if !carry.is_empty() {
            match it.next() {
                Some(i) => {
                    carry.extend_from_slice(&chunk[..i]);
                    let line = std::mem::take(&mut carry);
                    emit(&mut number, &line)?;
                    start = i + 1;
                }
                None => {
                    carry.extend_from_slice(chunk);
                    return Ok(());
                }
            }
        }
        for i in it {
            emit(&mut number, &chunk[start..i])?;
            start = i + 1;
        }
        carry.extend_from_slice(&chunk[start..]);
        Ok(())
    })?;
    if !carry.is_empty() {
        emit(&mut number, &carry)?;
    }
    Ok((hash, bytes))
}

/// The line without a `#` comment and surrounding white space.
pub fn strip_comment(line: &[u8]) -> &[u8] {
    let line = match line.iter().position(|&b| b == b'#') {
        Some(i) => &line[..i],
        None => line,
    };
    line.trim_ascii()
}
