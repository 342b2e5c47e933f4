//! Streaming line reader shared by the text logs: reads a file in large chunks, hashes and
//! counts its bytes on the way, and hands out lines with their numbers.

use crate::error::{Error, Result};
use sha2::{Digest, Sha256};
use std::io::Read;
use std::path::Path;
use std::sync::mpsc::sync_channel;

const CHUNK: usize = 1 << 20;

/// Reads `path` in chunks, feeding every chunk to `on_chunk`; returns the SHA-256 (hex) and
/// the size. The hash is computed on a second thread, chunk by chunk, while the next chunk is
/// processed; buffers go back and forth so none is allocated per chunk.
pub fn read_chunks(
    path: &Path,
    mut on_chunk: impl FnMut(&[u8]) -> Result<()>,
) -> Result<(String, u64)> {
    let mut f = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let (to_hasher, chunks) = sync_channel::<Vec<u8>>(2);
    let (give_back, spare) = sync_channel::<Vec<u8>>(4);
    std::thread::scope(|scope| {
        let hasher = scope.spawn(move || {
            let mut hasher = Sha256::new();
            for buf in chunks {
                hasher.update(&buf);
                let _ = give_back.try_send(buf);
            }
            hasher.finalize()
        });
        let mut total = 0u64;
        let result = (|| {
            loop {
                let mut buf = spare.try_recv().unwrap_or_default();
                buf.resize(CHUNK, 0);
                let n = loop {
                    match f.read(&mut buf) {
                        Ok(n) => break n,
                        Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                        Err(e) => return Err(Error::io(path, e)),
                    }
                };
                if n == 0 {
                    return Ok(());
                }
                buf.truncate(n);
                total += n as u64;
                on_chunk(&buf)?;
                if to_hasher.send(buf).is_err() {
                    return Err(Error::io(
                        path,
                        std::io::Error::other("the hashing thread stopped"),
                    ));
                }
            }
        })();
        drop(to_hasher);
        let digest = hasher
            .join()
            .map_err(|_| Error::io(path, std::io::Error::other("the hashing thread panicked")))?;
        result?;
        let hex = digest
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect::<String>();
        Ok((hex, total))
    })
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
        let mut it = memchr::memchr_iter(b'\n', chunk);
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
    let line = match memchr::memchr(b'#', line) {
        Some(i) => &line[..i],
        None => line,
    };
    line.trim_ascii()
}
