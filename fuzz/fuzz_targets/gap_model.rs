//! The gap model file (`gyrocomp gap --model BASE.toml`, and `sensor.toml`)
//! on arbitrary text: `gyrocomp::gap::parse_base` and
//! `gyrocomp::sim::model::SensorModel::parse` never panic; a model they
//! accept prints (`to_toml`) as a model `SensorModel::parse` accepts again.
#![no_main]
use gyrocomp::gap::parse_base;
use gyrocomp::sim::model::SensorModel;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let _ = parse_base(text);
    if let Ok(m) = SensorModel::parse(text) {
        let printed = m.to_toml();
        SensorModel::parse(&printed).unwrap_or_else(|e| panic!("the printed model is refused: {e}\n{printed}"));
    }
});
