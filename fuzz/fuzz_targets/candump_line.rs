//! One candump -l line (`gyrocomp::candump::parse_line`): never panics; a
//! classic data frame it accepts, written back by `write_line`, parses to
//! the same frame.
#![no_main]
use gyrocomp::candump::{parse_line, write_line};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|line: &[u8]| {
    let Ok(f) = parse_line(line) else { return };
    assert!(f.len <= 64);
    assert!(f.len <= 8 || f.fd, "a classic frame longer than 8 bytes");
    if !f.extended && !f.remote && !f.fd && !f.error {
        assert!(f.id <= 0x7FF);
        let mut out = Vec::new();
        write_line(&mut out, f.t_us, f.iface, f.id, f.payload());
        let g = parse_line(&out[..out.len() - 1]).expect("a written line parses");
        assert_eq!((g.t_us, g.iface, g.id, g.payload()), (f.t_us, f.iface, f.id, f.payload()));
    }
});
