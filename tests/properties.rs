//! Property tests: round trips, checksum coverage, covariance health.

use gyrocomp::adis::{builtin_profile, Assembler, InputIds, Push, RawFrame, RawSample};
use gyrocomp::config::OutputConfig;
use gyrocomp::estimator::ekf::{Ekf, Learn};
use gyrocomp::estimator::mekf::AidWord;
use gyrocomp::estimator::Estimate;
use gyrocomp::output::{decode, encode, StatusCounters};
use nalgebra::Vector3;
use proptest::prelude::*;

fn raw() -> impl Strategy<Value = RawSample> {
    (any::<[i16; 3]>(), any::<[i16; 3]>(), any::<[i16; 3]>(), any::<i16>(), any::<u16>(), any::<u16>())
        .prop_map(|(gyro, accel, magn, temp, diag, cnt)| RawSample { gyro, accel, magn, temp, diag, cnt })
}

fn push4(a: &mut Assembler, f: &[[u8; 8]; 4]) -> Vec<Push> {
    let ids = InputIds::DEFAULT.all();
    (0..4).map(|i| a.push(0, RawFrame::classic(ids[i], &f[i]))).collect()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, .. ProptestConfig::default() })]

    #[test]
    fn adis_encode_decode_round_trip(r in raw()) {
        let p = builtin_profile("adis16448").unwrap();
        let mut a = Assembler::new(p.clone(), InputIds::DEFAULT);
        let out = push4(&mut a, &r.encode());
        match out[3] {
            Push::Sample(s) => {
                prop_assert_eq!(s.cnt, r.cnt);
                prop_assert_eq!(s.diag, r.diag);
                for i in 0..3 {
                    prop_assert_eq!(s.gyro[i], r.gyro[i] as f64 * p.gyro_lsb);
                    prop_assert_eq!(s.accel[i], r.accel[i] as f64 * p.accel_lsb);
                    prop_assert_eq!(s.magn[i], r.magn[i] as f64 * p.magn_lsb);
                }
                // and back to the same registers
                let q = RawSample::quantise(&p, s.gyro, s.accel, s.magn, s.temp);
                prop_assert_eq!((q.gyro, q.accel, q.magn, q.temp), (r.gyro, r.accel, r.magn, r.temp));
            }
            other => prop_assert!(false, "no sample: {:?}", other),
        }
    }

    #[test]
    fn any_single_flipped_bit_is_caught(r in raw(), frame in 0usize..4, byte in 0usize..8, bit in 0u8..8) {
        let mut f = r.encode();
        f[frame][byte] ^= 1 << bit;
        let mut a = Assembler::new(builtin_profile("adis16448").unwrap(), InputIds::DEFAULT);
        let out = push4(&mut a, &f);
        // The corrupted sample is never delivered.
        prop_assert!(!out.iter().any(|p| matches!(p, Push::Sample(_))), "{:?}", out);
        prop_assert_eq!(a.counters.samples, 0);
        prop_assert!(a.counters.dropped() >= 1);
    }

    #[test]
    fn output_encode_decode_round_trip(
        rate in prop::array::uniform3(-300.0f64..300.0),
        att in (-180.0f64..180.0, -89.0f64..89.0, -180.0f64..180.0),
        bias in prop::array::uniform3(-10.0f64..10.0),
        temp in -40.0f64..120.0, mode in 0u8..3, fl in 0u16..0x0400, cnt in any::<u16>(),
        errors in any::<u64>(), lost in any::<u64>(), aid in (0u32..1 << 24, 0.0f64..655.0))
    {
        let aid = AidWord { status: aid.0, worst_ratio: aid.1 };
        let e = Estimate { cnt, rate, roll: att.0, pitch: att.1, yaw: att.2, bias, temp, mode, flags: fl, aid, ..Default::default() };
        let f = encode(&e, &StatusCounters { errors, lost }, &OutputConfig::default(), 0);
        let d = decode(&f);
        for i in 0..3 {
            prop_assert!((d.rate[i] - rate[i]).abs() <= 0.005 + 1e-9);
            prop_assert!((d.bias[i] - bias[i]).abs() <= 0.00025 + 1e-9);
        }
        prop_assert!((d.att[0] - att.0).abs() <= 0.005 + 1e-9);
        prop_assert!((d.att[1] - att.1).abs() <= 0.005 + 1e-9);
        prop_assert!((d.att[2] - att.2).abs() <= 0.005 + 1e-9);
        prop_assert!((d.temp - temp).abs() <= 0.005 + 1e-9);
        prop_assert_eq!((d.mode, d.flags, d.cnt), (mode, fl, cnt));
        prop_assert_eq!((d.errors as u64, d.lost as u64), (errors & 0xFF, lost & 0xFF));
        let a = d.aid.expect("EST_AID sent by default");
        prop_assert_eq!(a.status, aid.status);
        prop_assert!((a.worst_ratio - aid.worst_ratio).abs() <= 0.005 + 1e-9);
    }

    #[test]
    fn covariance_stays_symmetric_positive_definite(
        steps in prop::collection::vec(
            (prop::array::uniform3(-3.0f64..3.0), prop::array::uniform3(-3.2f64..3.2), 0u8..4, 0.0005f64..0.05),
            1..400)
    ) {
        let mut e = Ekf::new(Vector3::zeros(), Vector3::zeros(), 0.1, 0.01);
        for (om, z, kind, dt) in steps {
            e.predict(&Vector3::from(om), dt, 1e-6, 1e-10, &Vector3::zeros());
            let r = Vector3::new(3e-4, 3e-4, 3e-3);
            let z = Vector3::new(z[0], z[1].clamp(-1.5, 1.5), z[2]);
            match kind {
                0 => { e.update(&z, &r, true, Learn::AnglesAndBias); }
                1 => { e.update(&z, &r, false, Learn::AnglesAndBias); }
                2 => { e.update(&z, &(r * 50.0), true, Learn::AnglesOnly); }
                _ => {}
            }
            let p = e.covariance();
            prop_assert!((p - p.transpose()).abs().max() < 1e-12);
            let eig = p.symmetric_eigenvalues();
            prop_assert!(eig.min() > 0.0, "eigenvalues {:?}", eig);
            prop_assert!(e.is_finite());
        }
    }
}
