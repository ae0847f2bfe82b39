//! Text inputs read whole, with an error that says where the text stops
//! being UTF-8 (std's "stream did not contain valid UTF-8" names neither the
//! line nor the column, and callers add the file).

use std::io;
use std::path::Path;

/// Read into `buf` until it is full or the reader ends (a short first
/// read is not the end): the bytes read.
pub fn read_up_to(r: &mut impl io::Read, buf: &mut [u8]) -> io::Result<usize> {
    let mut n = 0;
    while n < buf.len() {
        match r.read(&mut buf[n..])? {
            0 => break,
            k => n += k,
        }
    }
    Ok(n)
}

/// The file as a string; a file that is not UTF-8 is an `InvalidData` error
/// naming the line, column and byte where it stops being text.
pub fn read(path: &Path) -> io::Result<String> {
    from_bytes(std::fs::read(path)?)
}

/// [`read`] of bytes already read (a gunzipped file, say).
pub fn from_bytes(bytes: Vec<u8>) -> io::Result<String> {
    String::from_utf8(bytes).map_err(|e| {
        let at = e.utf8_error().valid_up_to();
        io::Error::new(io::ErrorKind::InvalidData, not_text(e.as_bytes(), at))
    })
}

/// [`from_bytes`] of borrowed bytes.
pub fn str_of(bytes: &[u8]) -> io::Result<&str> {
    std::str::from_utf8(bytes).map_err(|e| io::Error::new(io::ErrorKind::InvalidData, not_text(bytes, e.valid_up_to())))
}

/// The bytes of a file read whole, gunzipped when they start with gzip's
/// magic number (0x1f 0x8b), as they are otherwise.
pub fn gunzip(bytes: &[u8]) -> io::Result<std::borrow::Cow<'_, [u8]>> {
    if !bytes.starts_with(&[0x1f, 0x8b]) {
        return Ok(std::borrow::Cow::Borrowed(bytes));
    }
    let mut out = Vec::new();
    io::Read::read_to_end(&mut flate2::read::MultiGzDecoder::new(bytes), &mut out)?;
    Ok(std::borrow::Cow::Owned(out))
}

/// "not UTF-8 text: line L, column C (byte 0xNN)" for `bytes` invalid at `at`.
pub fn not_text(bytes: &[u8], at: usize) -> String {
    let before = &bytes[..at];
    let line = before.iter().filter(|b| **b == b'\n').count() + 1;
    let start = before.iter().rposition(|b| *b == b'\n').map_or(0, |p| p + 1);
    let column = String::from_utf8_lossy(&before[start..]).chars().count() + 1;
    format!("not UTF-8 text: line {line}, column {column} (byte {:#04x}); a binary file or another encoding", bytes[at])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_first_byte_that_is_not_text_is_named() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("c.toml");
        std::fs::write(&p, b"[input]\nrate_hz = 1\n# caf\xc3\xa9 \xff\n").unwrap();
        let e = read(&p).unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::InvalidData);
        assert_eq!(e.to_string(), "not UTF-8 text: line 3, column 8 (byte 0xff); a binary file or another encoding");
        std::fs::write(&p, "ok\n").unwrap();
        assert_eq!(read(&p).unwrap(), "ok\n");
    }
}
