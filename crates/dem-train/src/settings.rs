//! The settings of a run a user may set, and the resume policy.
//!
//! A new run takes each unset value from the chosen architecture's defaults
//! ([`GanConfig::default`] for the residual head, [`GanConfig::thesis`] for
//! the thesis's network; the sampler's from [`Sampler`]); the defaults live
//! there and nowhere else. A resumed run keeps the settings of its
//! checkpoint: a value given again must equal the run's, so a resume can
//! never silently train a different model.

use dem_nn::train::checkpoint::Meta;
use dem_nn::train::{AdamConfig, GanConfig, Sampler};
use dem_nn::weights::Arch;

/// The settings given on the command line; `None` = not given.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Settings {
    /// Generator head.
    pub arch: Option<Arch>,
    /// Generator width w.
    pub width: Option<usize>,
    /// Records per batch.
    pub batch: Option<usize>,
    /// Adam learning rate.
    pub lr: Option<f32>,
    /// Weight of the cycle terms.
    pub lambda_cyc: Option<f32>,
    /// Weight of the paired terms.
    pub lambda_pair: Option<f32>,
    /// Weight of the paired height term.
    pub lambda_height: Option<f32>,
    /// Share of the epochs at the full learning rate.
    pub decay_from: Option<f32>,
    /// Share of each batch drawn from train pairs.
    pub paired_fraction: Option<f64>,
    /// Seed of initialisation, sampling and the sensor model's draw.
    pub seed: Option<u64>,
}

impl Settings {
    /// The network and loss settings of a new run: the given values over the
    /// architecture's defaults.
    pub fn gan_config(&self) -> GanConfig {
        let base = match self.arch {
            Some(Arch::Thesis) => GanConfig::thesis(),
            _ => GanConfig::default(),
        };
        GanConfig {
            width: self.width.unwrap_or(base.width),
            adam: AdamConfig { lr: self.lr.unwrap_or(base.adam.lr), ..base.adam },
            lambda_cyc: self.lambda_cyc.unwrap_or(base.lambda_cyc),
            lambda_pair: self.lambda_pair.unwrap_or(base.lambda_pair),
            lambda_height: self.lambda_height.unwrap_or(base.lambda_height),
            decay_from: self.decay_from.unwrap_or(base.decay_from),
            ..base
        }
    }

    /// Records per batch of a new run.
    pub fn batch(&self) -> usize {
        self.batch.unwrap_or(Sampler::DEFAULT_BATCH)
    }

    /// Paired share of each batch of a new run.
    pub fn paired_fraction(&self) -> f64 {
        self.paired_fraction.unwrap_or(Sampler::DEFAULT_PAIRED_FRACTION)
    }

    /// Seed of a new run.
    pub fn seed(&self) -> u64 {
        self.seed.unwrap_or(0)
    }

    /// On resume: every setting given again must be the run's. The error
    /// names the first flag that differs.
    pub fn check_same(&self, m: &Meta) -> Result<(), String> {
        let c = &m.config;
        let clash = [
            ("--width", self.width.is_some_and(|v| v != c.width)),
            ("--batch", self.batch.is_some_and(|v| v != m.batch)),
            ("--lr", self.lr.is_some_and(|v| v != c.adam.lr)),
            ("--lambda-cyc", self.lambda_cyc.is_some_and(|v| v != c.lambda_cyc)),
            ("--lambda-pair", self.lambda_pair.is_some_and(|v| v != c.lambda_pair)),
            ("--lambda-height", self.lambda_height.is_some_and(|v| v != c.lambda_height)),
            ("--decay-from", self.decay_from.is_some_and(|v| v != c.decay_from)),
            ("--arch", self.arch.is_some_and(|v| v != c.arch)),
            ("--paired-fraction", self.paired_fraction.is_some_and(|v| v != m.paired_fraction)),
            ("--seed", self.seed.is_some_and(|v| v != m.seed)),
        ];
        match clash.iter().find(|(_, differs)| *differs) {
            Some((name, _)) => Err(format!("--resume: {name} differs from the run's checkpoint (leave it out to keep the run's)")),
            None => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use dem_nn::train::checkpoint;
    use dem_nn::train::CycleGan;

    #[test]
    fn unset_values_are_the_architectures_defaults() {
        assert_eq!(Settings::default().gan_config(), GanConfig::default());
        let thesis = Settings { arch: Some(Arch::Thesis), ..Settings::default() };
        assert_eq!(thesis.gan_config(), GanConfig::thesis());
        let s = Settings { arch: Some(Arch::Thesis), width: Some(8), lr: Some(1e-3), lambda_height: Some(2.0), ..Settings::default() };
        let c = s.gan_config();
        assert_eq!((c.arch, c.width, c.adam.lr, c.lambda_height), (Arch::Thesis, 8, 1e-3, 2.0));
        assert_eq!(c.lambda_pair, GanConfig::thesis().lambda_pair, "an unset value stays the thesis's");
        assert_eq!((Settings::default().batch(), Settings::default().paired_fraction(), Settings::default().seed()), (64, 0.5, 0));
    }

    #[test]
    fn a_resume_keeps_the_runs_settings_and_names_the_first_that_differs() {
        let s = Settings { width: Some(4), seed: Some(9), ..Settings::default() };
        let gan = CycleGan::new(s.gan_config(), 9);
        let meta = checkpoint::meta(&gan, 9, 16, 0.25, 0, 10);
        assert_eq!(Settings::default().check_same(&meta), Ok(()), "nothing given: the run's own");
        assert_eq!(s.check_same(&meta), Ok(()), "the same values given again");
        let e = Settings { batch: Some(64), ..s.clone() }.check_same(&meta).unwrap_err();
        assert!(e.contains("--batch differs"), "{e}");
        let e = Settings { seed: Some(1), arch: Some(Arch::Thesis), ..s }.check_same(&meta).unwrap_err();
        assert!(e.contains("--arch differs"), "{e}");
    }
}
