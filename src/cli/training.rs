//! What every command that trains a field shares on the command line: `--time-budget`, with one
//! meaning in `train`, `extract`, `remove` and `demo`, and the views held out of training
//! (`--hold-out`, `--hold-out-every`), with one meaning in `train`, `eval`, `extract` and
//! `remove`.

use clap::Args;
use objnerf::field::holdout::HoldOut;
use objnerf::fit::FitOptions;

/// `--hold-out RULE` or `--hold-out-every N`: the views left out of training, to score on.
#[derive(Args, Clone, Copy, Debug, Default)]
pub struct HoldOutArg {
    /// Leave views out of training to score on: 'llff' (views 0, 8, 16, ..., as the LLFF
    /// figures in the literature are scored), N (every N-th view, as --hold-out-every N) or
    /// 'none'.
    #[arg(
        long = "hold-out",
        value_name = "llff|N|none",
        conflicts_with = "hold_out_every"
    )]
    rule: Option<HoldOut>,
    /// Leave every N-th view out of training (views N/2, N/2 + N, ...; 0: none).
    #[arg(long, value_name = "N")]
    hold_out_every: Option<usize>,
}

impl HoldOutArg {
    /// The rule given, else `default` (the command's).
    pub fn or(self, default: HoldOut) -> HoldOut {
        match (self.rule, self.hold_out_every) {
            (Some(r), _) => r,
            (None, Some(n)) => HoldOut::every(n),
            (None, None) => default,
        }
    }
}

/// `--time-budget`: seconds of training, or `none` for no limit; absent, the command's default.
#[derive(Args, Clone, Copy, Debug, Default)]
pub struct TimeBudgetArg {
    /// Seconds of training, or 'none' for no limit (the steps alone end it). Default: the
    /// command's own (train: none; extract: 120 per object; remove: 300; demo: 90).
    #[arg(long = "time-budget", value_name = "SECONDS|none", value_parser = parse_budget)]
    time_budget: Option<Budget>,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Budget {
    Seconds(f64),
    Unlimited,
}

fn parse_budget(s: &str) -> Result<Budget, String> {
    if s.eq_ignore_ascii_case("none") {
        return Ok(Budget::Unlimited);
    }
    match s.parse::<f64>() {
        Ok(v) if v > 0.0 && v.is_finite() => Ok(Budget::Seconds(v)),
        _ => Err(format!(
            "'{s}' is not a time budget: give seconds above 0, or 'none' for no limit"
        )),
    }
}

impl TimeBudgetArg {
    /// The budget to train with: the one given, else `default` (the command's).
    pub fn or(self, default: Option<f64>) -> Option<f64> {
        match self.time_budget {
            None => default,
            Some(Budget::Unlimited) => None,
            Some(Budget::Seconds(s)) => Some(s),
        }
    }
}

/// `--appearance-lr`: each training view's colour correction, with one meaning in `train`,
/// `extract` and `remove`.
#[derive(Args, Clone, Copy, Debug)]
pub struct AppearanceArg {
    /// Learn a colour correction (gain and offset per channel) for each training view at this
    /// learning rate, for captures whose exposure or white balance drifts between frames
    /// (phone videos); renders, meshes and scores leave it out (0: off).
    #[arg(long = "appearance-lr", value_name = "RATE", value_parser = parse_rate,
          default_value_t = FitOptions::default().appearance_lr)]
    pub rate: f32,
}

fn parse_rate(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if v >= 0.0 && v.is_finite() => Ok(v),
        _ => Err(format!(
            "'{s}' is not a learning rate: give a number of at least 0 (0: off)"
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::super::{Cli, Command};
    use clap::Parser;

    /// The budget each training command resolves from `args` (after the command's required
    /// arguments).
    fn budget(command: &str, args: &[&str]) -> Result<Option<f64>, String> {
        let mut argv = vec!["objnerf", command];
        argv.extend(match command {
            "train" => vec!["scene", "--masks", "alpha", "--out", "m.objf"],
            "extract" => vec!["scene", "--view", "v.png", "--point", "1,2", "--out", "run"],
            "remove" => vec!["scene", "--segment", "seg", "--object", "mug", "--out", "o"],
            _ => vec![],
        });
        argv.extend(args);
        let cli = Cli::try_parse_from(argv).map_err(|e| e.to_string())?;
        Ok(match cli.command {
            Command::Train(c) => c.time_budget(),
            Command::Extract(c) => c.options().map_err(|e| e.to_string())?.fit.time_budget,
            Command::Remove(c) => c.options().field.fit.time_budget,
            Command::Demo(c) => c.options().fit.time_budget,
            _ => unreachable!("not a training command"),
        })
    }

    const COMMANDS: [&str; 4] = ["train", "extract", "remove", "demo"];

    #[test]
    fn time_budget_means_the_same_in_every_command() {
        for c in COMMANDS {
            assert_eq!(budget(c, &["--time-budget", "30"]), Ok(Some(30.0)), "{c}");
            assert_eq!(budget(c, &["--time-budget=2.5"]), Ok(Some(2.5)), "{c}");
            assert_eq!(budget(c, &["--time-budget", "none"]), Ok(None), "{c}");
            for bad in ["0", "-5", "inf", "soon"] {
                let e = budget(c, &[&format!("--time-budget={bad}")]).unwrap_err();
                assert!(e.contains("not a time budget"), "{c} {bad}: {e}");
            }
        }
    }

    /// The appearance rate each training command resolves from `args`.
    fn appearance(command: &str, args: &[&str]) -> Result<f32, String> {
        let mut argv = vec!["objnerf", command];
        argv.extend(match command {
            "train" => vec!["scene", "--masks", "alpha", "--out", "m.objf"],
            "extract" => vec!["scene", "--view", "v.png", "--point", "1,2", "--out", "run"],
            _ => vec!["scene", "--segment", "seg", "--object", "mug", "--out", "o"],
        });
        argv.extend(args);
        let cli = Cli::try_parse_from(argv).map_err(|e| e.to_string())?;
        Ok(match cli.command {
            Command::Train(c) => c.appearance.rate,
            Command::Extract(c) => c.options().map_err(|e| e.to_string())?.fit.appearance_lr,
            Command::Remove(c) => c.options().field.fit.appearance_lr,
            _ => unreachable!("not a command that learns appearance"),
        })
    }

    #[test]
    fn appearance_lr_means_the_same_in_every_command() {
        for c in ["train", "extract", "remove"] {
            assert_eq!(appearance(c, &[]), Ok(0.0), "{c}: off by default");
            assert_eq!(
                appearance(c, &["--appearance-lr", "0.003"]),
                Ok(0.003),
                "{c}"
            );
            for bad in ["-1", "inf", "fast"] {
                let e = appearance(c, &[&format!("--appearance-lr={bad}")]).unwrap_err();
                assert!(e.contains("not a learning rate"), "{c} {bad}: {e}");
            }
        }
    }

    #[test]
    fn each_command_keeps_its_default_budget() {
        let defaults: Vec<Option<f64>> = COMMANDS.iter().map(|c| budget(c, &[]).unwrap()).collect();
        assert_eq!(defaults, [None, Some(120.0), Some(300.0), Some(90.0)]);
    }
}
