//! `gyrocomp::candump::LineReader` over arbitrary bytes delivered in
//! arbitrary chunks: never panics, and returns exactly the lines of the input
//! (a line over `MAX_LINE` bytes as `TooLong`), numbered in order.
#![no_main]
use gyrocomp::candump::{LineError, LineReader, MAX_LINE};
use libfuzzer_sys::fuzz_target;
use std::io::Read;

/// Hands out the input in chunks whose sizes come from the input itself.
struct Chunks<'a> {
    data: &'a [u8],
    sizes: &'a [u8],
    k: usize,
}

impl Read for Chunks<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let want = if self.sizes.is_empty() { usize::MAX } else { self.sizes[self.k % self.sizes.len()] as usize * 7 + 1 };
        self.k += 1;
        let n = want.min(buf.len()).min(self.data.len());
        buf[..n].copy_from_slice(&self.data[..n]);
        self.data = &self.data[n..];
        Ok(n)
    }
}

fuzz_target!(|input: &[u8]| {
    let (sizes, data) = input.split_at(input.len().min(4));
    let mut r = LineReader::new(Chunks { data, sizes, k: 0 });
    // what the lines must be: split at '\n', no empty last line
    let mut want: Vec<&[u8]> = data.split(|&c| c == b'\n').collect();
    if want.last().is_some_and(|l| l.is_empty()) {
        want.pop();
    }
    let mut k = 0;
    while let Some(line) = r.next_line().expect("reading a slice never fails") {
        assert!(k < want.len(), "more lines than the input has");
        match line {
            Ok(l) => assert_eq!(l, want[k], "line {}", k + 1),
            Err(LineError::TooLong) => assert!(want[k].len() > MAX_LINE, "line {} of {} bytes reported too long", k + 1, want[k].len()),
            Err(e) => panic!("unexpected {e:?}"),
        }
        k += 1;
        assert_eq!(r.line_no, k as u64);
    }
    assert_eq!(k, want.len(), "lines missing");
});
