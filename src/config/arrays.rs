//! Fixed-length arrays read exactly: serde's own `[f64; N]` takes the first
//! `N` values of a TOML array and drops the rest without a word (the toml
//! deserializer does not check for leftovers). These refuse any other
//! length; toml adds the line and column. For the simulator's model and
//! ranges files (the config names each key, `schema::exact`).

use serde::de::Error as _;
use serde::{Deserialize, Deserializer};

/// An array of exactly `N` numbers (`#[serde(deserialize_with = "exactly")]`).
pub fn exactly<'de, D: Deserializer<'de>, const N: usize>(d: D) -> Result<[f64; N], D::Error> {
    let v = Vec::<f64>::deserialize(d)?;
    <[f64; N]>::try_from(v.as_slice()).map_err(|_| D::Error::custom(format!("expected an array of {N} numbers, got {} values", v.len())))
}

/// A 3x3 matrix: exactly three rows of exactly three numbers.
pub fn exactly_3x3<'de, D: Deserializer<'de>>(d: D) -> Result<[[f64; 3]; 3], D::Error> {
    let v = Vec::<Vec<f64>>::deserialize(d)?;
    let rows = v.len();
    let bad =
        || D::Error::custom(format!("expected 3 rows of 3 numbers, got {rows} rows of {:?}", v.iter().map(Vec::len).collect::<Vec<_>>()));
    let row = |r: &Vec<f64>| <[f64; 3]>::try_from(r.as_slice()).map_err(|_| bad());
    match v.as_slice() {
        [a, b, c] => Ok([row(a)?, row(b)?, row(c)?]),
        _ => Err(bad()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Deserialize, Debug)]
    struct T {
        #[serde(deserialize_with = "exactly")]
        v: [f64; 3],
        #[serde(default, deserialize_with = "exactly_3x3")]
        m: [[f64; 3]; 3],
    }

    #[test]
    fn only_the_exact_length_is_taken() {
        let t: T = toml::from_str("v = [1, 2, 3]\nm = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]").unwrap();
        assert_eq!(t.v, [1.0, 2.0, 3.0]);
        assert_eq!(t.m[2][2], 1.0);
        for bad in [
            "v = [1, 2, 3, 45]",
            "v = [1, 2]",
            "v = [1, 2, 3]\nm = [[1, 0, 0], [0, 1, 0], [0, 0, 1, 9]]",
            "v = [1, 2, 3]\nm = [[1, 0, 0], [0, 1, 0]]",
        ] {
            let e = toml::from_str::<T>(bad).unwrap_err().to_string();
            assert!(e.contains("expected") && e.contains("line"), "{bad}: {e}");
        }
    }
}
