//! `gyrocomp::config::Config::parse` on arbitrary text: never panics; a
//! config it accepts prints (check-config's effective config) as a config it
//! accepts again, with the same meaning, and printing is a fixed point.
#![no_main]
use gyrocomp::config::Config;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let Ok(c) = Config::parse(text, "fuzz") else { return };
    let printed = c.to_toml();
    let back = Config::parse(&printed, "printed").unwrap_or_else(|e| panic!("the effective config is refused: {e}\n{printed}"));
    assert_eq!(back, c.effective());
    assert_eq!(back.to_toml(), printed);
});
