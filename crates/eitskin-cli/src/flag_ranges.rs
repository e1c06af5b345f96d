//! Every flag that takes a value, tried with 0, a negative number, NaN, infinity and 1e300: each
//! is refused by its own range check, naming the flag and quoting the value, or its acceptance
//! is listed here as documented. A flag added without either fails this test.

use clap::error::ErrorKind;

use crate::command;

/// The values every flag is tried with.
const BAD: [&str; 5] = ["0", "-1", "nan", "inf", "1e300"];

/// Flags whose value is text (a path, a name, an address, a list) and is checked where it is
/// used, by the file or name it points to.
const TEXT: &[(&str, &str)] = &[
    ("mesh", "out"),
    ("forward", "protocol"),
    ("forward", "inclusion"),
    ("forward", "mesh"),
    ("image", "reference"),
    ("image", "frame"),
    ("image", "select"),
    ("image", "reference-select"),
    ("image", "out"),
    ("image", "elements"),
    ("image", "png"),
    ("segment", "reference"),
    ("segment", "frame"),
    ("segment", "select"),
    ("segment", "reference-select"),
    ("segment", "out"),
    ("sensitivity", "out"),
    ("study", "out"),
    ("calibrate", "samples"),
    ("calibrate", "out"),
    ("calibrate", "reference"),
    ("evaluate", "calibration"),
    ("evaluate", "model"),
    ("evaluate", "samples"),
    ("evaluate", "reference"),
    ("evaluate", "out"),
    ("learn", "samples"),
    ("learn", "out"),
    ("learn", "held-out"),
    ("learn", "method"),
    ("learn", "plots"),
    ("learn", "reference"),
    ("robot-presses", "out"),
    ("robot-presses", "held-out"),
    ("run", "calibration"),
    ("run", "model"),
    ("run", "record"),
    ("run", "sensor"),
    ("run", "zenoh-config"),
    ("run", "connect"),
    ("run", "listen"),
    ("serve", "zenoh-config"),
    ("serve", "connect"),
    ("serve", "listen"),
    ("convergence", "protocol"),
    ("convergence", "inclusion"),
];

/// Numbers a flag takes as they are, with what they mean (each stated in the flag's help).
const ACCEPTED: &[(&str, &str, &str)] = &[
    ("study", "seed", "0"),
    ("run", "seed", "0"),
    ("run", "noise", "0"),              // noise-free frames
    ("study", "noise", "0"),            // noise-free frames
    ("study", "sweep-presses", "0"),    // the sweep left out
    ("study", "learning-presses", "0"), // the learned calibration left out
    ("run", "rate", "0"),               // a capture as fast as possible
    ("run", "baseline-rate", "0"),      // no baseline update
    ("run", "viewer", "0"),             // any free port
    ("run", "ros-domain", "0"),         // ROS's default domain
    ("robot-presses", "seed", "0"),
    ("robot-presses", "held-out-count", "0"), // no held-out file
    ("robot-presses", "noise", "0"),          // noise-free presses
];

#[test]
fn every_flag_refuses_numbers_out_of_its_range_or_documents_them() {
    let root = command();
    let mut undocumented = Vec::new();
    let mut seen_text = Vec::new();
    for sub in root.get_subcommands().filter(|s| s.get_name() != "help") {
        let name = sub.get_name();
        // Each required flag with a value its parser takes (an output's name its format's).
        let required: Vec<(String, &str)> = sub
            .get_arguments()
            .filter(|a| a.is_required_set())
            .filter_map(|a| {
                let flag = format!("--{}", a.get_long()?);
                let taken = |v: &&str| match sub.clone().try_get_matches_from([name, &flag, v]) {
                    Err(e) => !matches!(e.kind(), ErrorKind::ValueValidation | ErrorKind::InvalidValue),
                    Ok(_) => true,
                };
                Some((flag.clone(), ["x", "x.csv", "x.json"].into_iter().find(taken)?))
            })
            .collect();
        for arg in sub.get_arguments().filter(|a| a.get_action().takes_values()) {
            let Some(flag) = arg.get_long() else {
                // The one positional argument of every command: the spec file's path (serve's:
                // the fleet's).
                let expected = if name == "serve" { "fleet" } else { "spec" };
                assert_eq!(arg.get_id(), expected, "{name}");
                continue;
            };
            if TEXT.contains(&(name, flag)) {
                seen_text.push((name, flag));
                continue;
            }
            for bad in BAD {
                let mut argv = vec!["eitskin".to_string(), name.to_string()];
                for (other, value) in required.iter().filter(|(r, _)| *r != format!("--{flag}")) {
                    argv.extend([other.clone(), value.to_string()]);
                }
                argv.extend([format!("--{flag}"), bad.to_string()]);
                match command().try_get_matches_from(&argv) {
                    Ok(_) if ACCEPTED.contains(&(name, flag, bad)) => {}
                    Ok(_) => undocumented.push(format!("{name} --{flag} {bad}")),
                    Err(e) => {
                        let text = e.to_string();
                        assert!(
                            matches!(e.kind(), ErrorKind::ValueValidation | ErrorKind::InvalidValue),
                            "{argv:?}: {:?}: {text}",
                            e.kind()
                        );
                        assert!(
                            text.contains(&format!("'{bad}'")) && text.contains(&format!("--{flag}")),
                            "{argv:?}: the message names neither the flag nor the value: {text}"
                        );
                        assert!(text.lines().next().is_some_and(|l| l.len() < 400), "{text}");
                    }
                }
            }
        }
    }
    assert!(undocumented.is_empty(), "taken without a range check or a documented acceptance: {undocumented:#?}");
    let stale: Vec<_> = TEXT.iter().filter(|t| !seen_text.contains(t)).collect();
    assert!(stale.is_empty(), "listed as text but not a flag: {stale:?}");
}
