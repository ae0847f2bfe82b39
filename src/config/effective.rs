//! The configuration in effect: the part profile with the `[input]`
//! overrides applied, and the effective config printed as TOML
//! (`gyrocomp check-config`), a file that parses back to itself.

use super::Config;
use crate::adis::{builtin_profile, Profile};

impl Config {
    /// The configuration in effect: the sample rate and the scales resolved
    /// from the profile (what [`Config::profile`] gives), everything else as is.
    pub fn effective(&self) -> Config {
        let mut c = self.clone();
        let p = self.profile();
        c.input.rate_hz = p.rate_hz;
        if !self.input.format.is_adis() {
            // the DBC gives the scales; printed as comments by `to_toml`
            return c;
        }
        c.input.gyro_lsb = Some(p.gyro_lsb);
        c.input.accel_lsb = Some(p.accel_lsb);
        c.input.magn_lsb = Some(p.magn_lsb);
        c.input.temp_lsb = Some(p.temp_lsb);
        c.input.temp_offset = Some(p.temp_offset);
        c
    }

    /// The effective profile: the named built-in with the overrides applied.
    pub fn profile(&self) -> Profile {
        let mut p = builtin_profile(&self.input.profile).unwrap_or_else(|| builtin_profile("adis16448").unwrap());
        let i = &self.input;
        if !i.format.is_adis() {
            // a DBC-described unit: its rate as configured, no magnetometer;
            // the scales are the DBC's (the ADIS ones are not used)
            p.name = "dbc".into();
            p.magnetometer = false;
        }
        if i.rate_hz > 0.0 {
            p.rate_hz = i.rate_hz;
        }
        p.gyro_lsb = i.gyro_lsb.unwrap_or(p.gyro_lsb);
        p.accel_lsb = i.accel_lsb.unwrap_or(p.accel_lsb);
        p.magn_lsb = i.magn_lsb.unwrap_or(p.magn_lsb);
        p.temp_lsb = i.temp_lsb.unwrap_or(p.temp_lsb);
        p.temp_offset = i.temp_offset.unwrap_or(p.temp_offset);
        p
    }

    /// The initial 1-sigma of the gyro bias, deg/s: `[ekf] init_bias_sigma`
    /// or the part profile's turn-on bias sigma.
    pub fn init_bias_sigma(&self) -> f64 {
        self.ekf.init_bias_sigma.unwrap_or_else(|| self.profile().gyro_bias_sigma)
    }

    /// The effective config ([`Config::effective`]) as TOML text: every key,
    /// CAN IDs in hex. It is a valid config file that parses back to the
    /// same effective config.
    pub fn to_toml(&self) -> String {
        let text = toml::to_string(&self.effective()).unwrap_or_else(|e| format!("# cannot serialise: {e}\n"));
        let mut out = if self.input.format.is_adis() {
            format!(
                "# effective configuration: every key with its value in force; rate_hz and the scales are {}'s unless overridden\n",
                self.input.profile
            )
        } else {
            "# effective configuration: every key with its value in force; the input is described by its DBC\n".to_string()
        };
        if let Some(plan) = &self.input.plan.0 {
            out += &format!("# input mapping resolved from {}:\n", plan.path);
            for l in &plan.lines {
                out += &format!("#   {l}\n");
            }
            if let Some(r) = crate::estimator::reduced_params(self) {
                out += &format!(
                    "# reduced axes ({} not mapped): the yaw-rate bias (learned at standstills{}{}) and heading; roll, pitch and the x, y rates and biases are not estimated (EST_AID Invalid* bits; docs/estimator.md#reduced-axes)\n",
                    plan.missing_motion().join(", "),
                    if r.speed_aided { " and straight cruises, by the wheel speeds" } else { " read from the quiet yaw rate and ax, ay" },
                    if r.temp_mapped && self.thermal.enabled { ", moved by the thermal curve" } else { ", no thermal curve: no temperature mapped" },
                );
            }
        }
        let mut section = "";
        for line in text.lines() {
            if line.starts_with('[') {
                section = line;
            }
            // a DBC input has no ADIS profile or frame IDs
            let adis_only = section == "[input.ids]" || (section == "[input]" && line.starts_with("profile = "));
            if !self.input.format.is_adis() && adis_only {
                continue;
            }
            let hex = match line.split_once(" = ") {
                Some((k, v)) if section == "[input.ids]" || (section == "[output]" && k.ends_with("_id")) => {
                    v.parse::<u32>().ok().map(|n| format!("{k} = 0x{n:03X}"))
                }
                _ => None,
            };
            out += hex.as_deref().unwrap_or(line);
            out += "\n";
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn effective_config_resolves_the_rate_prints_hex_ids_and_round_trips() {
        for (profile, rate) in [("adis16448", "204.8"), ("adis16405", "819.2"), ("adis16465-1", "2000.0")] {
            let c = Config::parse(&format!("[input]\nprofile = \"{profile}\"\nrate_hz = 0.0\n"), "t").unwrap();
            let text = c.to_toml();
            assert!(text.contains(&format!("rate_hz = {rate}\n")), "{text}");
            let back = Config::parse(&text, "printed").unwrap_or_else(|e| panic!("{e}\n{text}"));
            assert_eq!(back, c.effective());
            assert_eq!(back.profile(), c.profile());
            assert_eq!(back.to_toml(), text, "printing is a fixed point");
        }
        let c = Config::parse("[input.ids]\naux = 0x7FF\n[output]\nstatus_id = 0x20\n", "t").unwrap();
        let text = c.to_toml();
        for want in
            ["gyro = 0x100\n", "aux = 0x7FF\n", "rate_id = 0x110\n", "status_id = 0x020\n", "aid_id = 0x114\n", "aid_frame = true\n"]
        {
            assert!(text.contains(want), "{want} missing:\n{text}");
        }
        assert_eq!(Config::parse(&text, "printed").unwrap(), c.effective());
        // the shipped example round-trips too
        let shipped = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/config/gyrocomp.toml")).unwrap();
        let c = Config::parse(&shipped, "gyrocomp.toml").unwrap();
        assert_eq!(Config::parse(&c.to_toml(), "printed").unwrap(), c.effective());
    }

    #[test]
    fn overrides_apply() {
        let c = Config::parse("[input]\nprofile = \"adis16405\"\nrate_hz = 100.0\ngyro_lsb = 0.02", "t").unwrap();
        let p = c.profile();
        assert_eq!(p.rate_hz, 100.0);
        assert_eq!(p.gyro_lsb, 0.02);
        assert_eq!(p.accel_lsb, 3.33e-3);
    }
}
