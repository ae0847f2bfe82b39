//! The wheel-speed path: arbitrary text as the car's DBC into
//! `gyrocomp::speed::SpeedDecoder::from_dbc_text` (the message and signals of
//! `config/example-car.dbc`), then the rest of the input as frames to decode.
//! Never panics; whatever it decodes is finite.
#![no_main]
use gyrocomp::config::SpeedConfig;
use gyrocomp::speed::SpeedDecoder;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    // [text] 0x00 [frames: len byte + payload ...]
    let split = data.iter().position(|&b| b == 0).unwrap_or(data.len());
    let Ok(text) = std::str::from_utf8(&data[..split]) else { return };
    let cfg = SpeedConfig {
        dbc: "car.dbc".into(),
        message: "WHEEL_SPEEDS".into(),
        signals: vec!["WHEEL_SPEED_RL".into(), "WHEEL_SPEED_RR".into()],
        ..SpeedConfig::default()
    };
    let Ok(dec) = SpeedDecoder::from_dbc_text(text, "fuzz", &cfg) else { return };
    let mut rest = data.get(split + 1..).unwrap_or(&[]);
    while let Some((&n, tail)) = rest.split_first() {
        let n = (n as usize % 9).min(tail.len());
        if let Ok(v) = dec.decode(&tail[..n]) {
            assert!(v.is_finite(), "decoded {v}");
        }
        rest = &tail[n..];
    }
});
