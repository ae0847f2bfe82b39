//! The simulator's truth, bias and vehicle readers (`evaluate --input DIR`:
//! `gyrocomp::sim::parse_truth`, `parse_table` with the bias.csv and
//! vehicle.csv headers) on arbitrary text: never panics; what they accept is
//! finite with t strictly increasing.
#![no_main]
use gyrocomp::sim::{parse_table, parse_truth, BIAS_HEADER, VEHICLE_HEADER};
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let p = Path::new("fuzz.csv");
    if let Ok(rows) = parse_truth(text, p) {
        assert!(rows.windows(2).all(|w| w[1].t > w[0].t));
        for r in &rows {
            assert!(r.t.is_finite() && r.temp.is_finite());
            assert!(r.att.iter().chain(&r.rate).chain(&r.f).all(|v| v.is_finite()));
        }
    }
    for header in [BIAS_HEADER, VEHICLE_HEADER] {
        let check = |rows: Vec<Vec<f64>>| {
            assert!(rows.windows(2).all(|w| w[1][0] > w[0][0]));
            assert!(rows.iter().flatten().all(|v| v.is_finite()));
        };
        if header == BIAS_HEADER {
            if let Ok(rows) = parse_table::<4>(text, p, header) {
                check(rows.iter().map(|r| r.to_vec()).collect());
            }
        } else if let Ok(rows) = parse_table::<6>(text, p, header) {
            check(rows.iter().map(|r| r.to_vec()).collect());
        }
    }
});
