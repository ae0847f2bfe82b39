//! `gyrocomp::reference::refcsv::parse_reference` (the measured reference,
//! `evaluate --reference`) on arbitrary text: never panics; what it accepts
//! has finite angles on valid rows, t finite and strictly increasing, and at
//! least one valid row.
#![no_main]
use gyrocomp::reference::refcsv::parse_reference;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let Ok(r) = parse_reference(text, "fuzz.csv") else { return };
    assert!(r.rows.iter().any(|x| x.att.is_some()));
    assert!(r.rows.windows(2).all(|w| w[1].t > w[0].t));
    for x in &r.rows {
        assert!(x.t.is_finite());
        if let Some(a) = x.att {
            assert!(a.iter().all(|v| v.is_finite()));
        }
    }
});
