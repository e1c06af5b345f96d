//! Stimulation and measurement patterns, as data.
//!
//! A [`Protocol`] is a list of stimulations (the current through each electrode, in A; they
//! sum to zero) and a list of measurements (a stimulation index and a weight per electrode;
//! the weights sum to zero, so a measurement is a voltage difference, in V). Electrodes are
//! indexed from 0 here and numbered from 1 in files and messages. Every stimulation drives
//! some current and every measurement weighs some electrode, and no current is past
//! [`MAX_CURRENT`] nor weight past [`MAX_WEIGHT`] in size.
//!
//! The built-in protocols and their frame order (k the stimulation, m the measured pair,
//! both from 0 and taken modulo L; "skip driven" drops every pair that shares an electrode
//! with the drive, keeping the order of the rest):
//!
//! | protocol | stimulation k | measurement | L = 16 | L = 32 |
//! |---|---|---|---|---|
//! | [`Protocol::two_terminal`] | +1 A at a, −1 A at b | U_a − U_b, pairs a < b in lexicographic order | 120 | 496 |
//! | [`Protocol::adjacent`] (skip driven) | −1 A at k, +1 A at k+1 | U_m − U_{m+1}, m = 0 … L−1 | 208 | 928 |
//! | [`Protocol::adjacent`] (all) | as above | row L·k + m | 256 | 1024 |
//! | [`Protocol::opposite`] | −1 A at k, +1 A at k+⌊L/2⌋ | U_m − U_{m+1}, skip driven | 192 | 896 |
//! | [`Protocol::skip`] (skip s, skip driven) | −1 A at k, +1 A at k+s+1 | U_m − U_{m+s+1} | 208 (224 for s = 7) | 928 (960 for s = 15) |
//! | [`Protocol::skip`] (all) | as above | row L·k + m | 256 | 1024 |
//!
//! Measurement-major order inside each stimulation, stimulations in order k = 0 … L−1.
//! EIDORS' `mk_stim_patterns(L,1,[0,1],[0,1],{'no_meas_current'},1)` is `adjacent` row for
//! row, sign included (checked against its exported quads in `tests/forward_eidors.rs`);
//! pyEIT's `protocol.create(L, dist_exc=s+1, step_meas=s+1, parser_meas="std")` drives +1 A at
//! k and measures U_{m+s+1} − U_m: both signs flipped, so every value is the same as `skip`'s.
//! The OpenEIT firmware's 32-electrode adjacent table (928 values) is `adjacent`'s order, and
//! its 16-electrode opposition table (192 values) is `opposite`'s order and sign; the board
//! reports magnitudes |Z| (see `docs/src/openeit.md`).

use thiserror::Error;

/// The most electrodes a protocol (and a spec's `electrodes.count`) takes.
pub const MAX_ELECTRODES: usize = 256;

/// The largest current a stimulation may put through an electrode, in A (either sign): a
/// thousand times what an EIT board drives (mA); past it, a value is a unit slip.
pub const MAX_CURRENT: f64 = 1e3;

/// The largest weight a measurement may give an electrode's voltage, in size (dimensionless;
/// boards weigh by ±1, or a gain of a few).
pub const MAX_WEIGHT: f64 = 1e3;

/// What is wrong with a protocol; indices in messages are 1-based, as a user counts.
#[derive(Debug, Error, PartialEq)]
pub enum ProtocolError {
    /// More electrodes than a sensor may have ([`MAX_ELECTRODES`]).
    #[error("a protocol of {electrodes} electrodes: a sensor has at most {max}")]
    TooManyElectrodes {
        /// Electrode count asked for.
        electrodes: usize,
        /// The most a sensor has.
        max: usize,
    },
    /// A protocol needs at least two electrodes and one measurement.
    #[error("a protocol needs at least 2 electrodes and 1 measurement, got {electrodes} electrodes and {measurements} measurements")]
    Empty {
        /// Electrode count.
        electrodes: usize,
        /// Measurement count.
        measurements: usize,
    },
    /// A pattern has a value per electrode, and this one has the wrong count.
    #[error("{what} {index} has {got} values, expected one per electrode ({expected})")]
    WrongLength {
        /// "stimulation" or "measurement".
        what: &'static str,
        /// 1-based index of the pattern.
        index: usize,
        /// Electrode count.
        expected: usize,
        /// Values found.
        got: usize,
    },
    /// Currents or weights must sum to zero (current is conserved; a measurement is a difference).
    #[error("{what} {index} sums to {sum}, not 0: currents must be conserved and measurements must be differences")]
    NotBalanced {
        /// "stimulation" or "measurement".
        what: &'static str,
        /// 1-based index of the pattern.
        index: usize,
        /// The sum found.
        sum: f64,
    },
    /// A value is NaN or infinite.
    #[error("{what} {index} holds a value that is not finite")]
    NotFinite {
        /// "stimulation" or "measurement".
        what: &'static str,
        /// 1-based index of the pattern.
        index: usize,
    },
    /// A stimulation whose currents are all 0, or a measurement whose weights are all 0.
    #[error("{what} {index} {reason}", reason = if *what == "stimulation" { "drives no current: every electrode's current is 0 A" } else { "weighs no electrode: every weight is 0" })]
    Nothing {
        /// "stimulation" or "measurement".
        what: &'static str,
        /// 1-based index of the pattern.
        index: usize,
    },
    /// A current past [`MAX_CURRENT`] or a weight past [`MAX_WEIGHT`] in size.
    #[error(
        "{what} {index} {} on electrode {electrode}: past ±{max:e}{}, more than any board uses",
        too_large(what, *value), pattern_unit(what)
    )]
    TooLarge {
        /// "stimulation" or "measurement".
        what: &'static str,
        /// 1-based index of the pattern.
        index: usize,
        /// 1-based electrode.
        electrode: usize,
        /// The current (A) or weight found.
        value: f64,
        /// [`MAX_CURRENT`] or [`MAX_WEIGHT`].
        max: f64,
    },
    /// A measurement names a stimulation that does not exist.
    #[error("measurement {index} uses stimulation {stimulation}, but there are only {count}")]
    NoSuchStimulation {
        /// 1-based measurement index.
        index: usize,
        /// 1-based stimulation it names.
        stimulation: usize,
        /// Stimulations in the protocol.
        count: usize,
    },
    /// A quad names an electrode outside 1..=L.
    #[error("row {row} names electrode {electrode}, but electrodes are numbered 1 to {count}")]
    NoSuchElectrode {
        /// 1-based row of the quad list.
        row: usize,
        /// The electrode number found (1-based).
        electrode: usize,
        /// Electrode count.
        count: usize,
    },
    /// A skip protocol whose drive pair would be one electrode (skip + 1 ≥ L).
    #[error("skip-{skip} pairs electrode k with k + {pair_offset}, which needs more than {electrodes} electrodes; use a skip of at most {max}", pair_offset = skip + 1, max = electrodes.saturating_sub(2))]
    SkipTooLarge {
        /// The skip s (electrodes between the pair).
        skip: usize,
        /// Electrode count L.
        electrodes: usize,
    },
    /// A quad drives or measures between an electrode and itself.
    #[error("row {row} pairs electrode {electrode} with itself")]
    SamePair {
        /// 1-based row of the quad list.
        row: usize,
        /// The electrode (1-based).
        electrode: usize,
    },
}

/// The unit of a pattern's values, as a message writes it after a number: " A" for a
/// stimulation's currents, none for a measurement's weights.
fn pattern_unit(what: &str) -> &'static str {
    if what == "stimulation" {
        " A"
    } else {
        ""
    }
}

/// "puts a current of 5 A" or "gives a weight of 5", for [`ProtocolError::TooLarge`].
fn too_large(what: &str, value: f64) -> String {
    let value = crate::spec::Quantity::written(value, "");
    match what {
        "stimulation" => format!("puts a current of {value} A"),
        _ => format!("gives a weight of {value}"),
    }
}

/// One measurement: which stimulation is applied and the weight of each electrode's voltage.
#[derive(Debug, Clone, PartialEq)]
pub struct Measurement {
    /// Index of the stimulation, 0-based.
    pub stimulation: usize,
    /// Weight of each electrode voltage (dimensionless, summing to 0).
    pub weights: Vec<f64>,
}

/// Stimulation and measurement patterns: what the acquisition board does in one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Protocol {
    description: String,
    electrode_count: usize,
    stimulations: Vec<Vec<f64>>,
    measurements: Vec<Measurement>,
}

const BALANCE_TOL: f64 = 1e-9;

impl Protocol {
    /// A checked protocol from its patterns: currents in A per electrode, weights per electrode.
    pub fn new(
        description: impl Into<String>,
        electrode_count: usize,
        stimulations: Vec<Vec<f64>>,
        measurements: Vec<Measurement>,
    ) -> Result<Protocol, ProtocolError> {
        check_electrode_count(electrode_count)?;
        if electrode_count < 2 || measurements.is_empty() {
            return Err(ProtocolError::Empty { electrodes: electrode_count, measurements: measurements.len() });
        }
        let check = |what, index: usize, values: &[f64]| {
            if values.len() != electrode_count {
                return Err(ProtocolError::WrongLength {
                    what,
                    index: index + 1,
                    expected: electrode_count,
                    got: values.len(),
                });
            }
            if values.iter().any(|v| !v.is_finite()) {
                return Err(ProtocolError::NotFinite { what, index: index + 1 });
            }
            let max = if what == "stimulation" { MAX_CURRENT } else { MAX_WEIGHT };
            if let Some(e) = values.iter().position(|v| v.abs() > max) {
                return Err(ProtocolError::TooLarge {
                    what,
                    index: index + 1,
                    electrode: e + 1,
                    value: values[e],
                    max,
                });
            }
            if values.iter().all(|&v| v == 0.0) {
                return Err(ProtocolError::Nothing { what, index: index + 1 });
            }
            let sum: f64 = values.iter().sum();
            let scale = values.iter().map(|v| v.abs()).sum::<f64>().max(1.0);
            if sum.abs() > BALANCE_TOL * scale {
                return Err(ProtocolError::NotBalanced { what, index: index + 1, sum });
            }
            Ok(())
        };
        for (i, s) in stimulations.iter().enumerate() {
            check("stimulation", i, s)?;
        }
        for (i, m) in measurements.iter().enumerate() {
            check("measurement", i, &m.weights)?;
            if m.stimulation >= stimulations.len() {
                return Err(ProtocolError::NoSuchStimulation {
                    index: i + 1,
                    stimulation: m.stimulation + 1,
                    count: stimulations.len(),
                });
            }
        }
        Ok(Protocol { description: description.into(), electrode_count, stimulations, measurements })
    }

    /// The paper's protocol: each pair (a, b), a < b, driven with +1 A at a and −1 A at b and
    /// measured as U_a − U_b; order (1,2), (1,3) … (L−1,L); 120 measurements for L = 16.
    pub fn two_terminal(electrode_count: usize) -> Result<Protocol, ProtocolError> {
        check_electrode_count(electrode_count)?;
        let mut quads = Vec::new();
        for a in 0..electrode_count {
            for b in a + 1..electrode_count {
                quads.push([a, b, a, b]);
            }
        }
        Protocol::from_quads0(
            format!("two-terminal, all {} pairs of {electrode_count} electrodes", quads.len()),
            electrode_count,
            &quads,
        )
    }

    /// Adjacent drive, adjacent measurement, EIDORS' `mk_stim_patterns(L,1,[0,1],[0,1],…,1)`
    /// row for row: stimulation k (k = 0 … L−1) puts −1 A at k and +1 A at k+1; measurement m
    /// (m = 0 … L−1, in that order) is U_m − U_{m+1}, indices modulo L. With `skip_driven`
    /// (EIDORS' `'no_meas_current'`) the pairs touching a driven electrode are left out:
    /// L(L−3) values, 208 for L = 16, 928 for L = 32 (the OpenEIT firmware's 32-electrode
    /// order); without (`'meas_current'`), all L² are kept and row L·k + m is pair m of
    /// stimulation k (256 for L = 16).
    pub fn adjacent(electrode_count: usize, skip_driven: bool) -> Result<Protocol, ProtocolError> {
        check_electrode_count(electrode_count)?;
        let quads = drive_and_measure_quads(electrode_count, 1, 1, skip_driven);
        let variant = if skip_driven { "skipping driven electrodes" } else { "all pairs" };
        Protocol::from_quads0(
            format!(
                "adjacent drive, adjacent measurement {variant}: {} measurements of {electrode_count} electrodes",
                quads.len()
            ),
            electrode_count,
            &quads,
        )
    }

    /// Opposite drive, adjacent measurement: stimulation k (k = 0 … L−1) puts −1 A at k and
    /// +1 A at k + ⌊L/2⌋; measurement m (m = 0 … L−1, in that order) is U_m − U_{m+1}, pairs
    /// touching a driven electrode left out: L(L−4) values for even L, 192 for L = 16 (the
    /// OpenEIT firmware's 16-electrode opposition table, row for row).
    pub fn opposite(electrode_count: usize) -> Result<Protocol, ProtocolError> {
        check_electrode_count(electrode_count)?;
        let quads = drive_and_measure_quads(electrode_count, electrode_count / 2, 1, true);
        Protocol::from_quads0(
            format!(
                "opposite drive, adjacent measurement skipping driven electrodes: {} measurements of {electrode_count} electrodes",
                quads.len()
            ),
            electrode_count,
            &quads,
        )
    }

    /// Skip-s drive and measurement (pyEIT's `dist_exc = step_meas = s + 1`): stimulation k
    /// (k = 0 … L−1) puts −1 A at k and +1 A at k+s+1; measurement m (m = 0 … L−1, in that
    /// order) is U_m − U_{m+s+1}, indices modulo L. With `skip_driven` the pairs sharing an
    /// electrode with the drive are left out: L(L−3) values (208 for L = 16), or L(L−2) when
    /// 2(s+1) = L (224 for L = 16, s = 7); without, all L² are kept, row L·k + m. Skip 0 is
    /// [`Protocol::adjacent`], pattern for pattern.
    pub fn skip(electrode_count: usize, skip: usize, skip_driven: bool) -> Result<Protocol, ProtocolError> {
        if skip + 1 >= electrode_count.max(2) {
            return Err(ProtocolError::SkipTooLarge { skip, electrodes: electrode_count });
        }
        let quads = drive_and_measure_quads(electrode_count, skip + 1, skip + 1, skip_driven);
        let variant = if skip_driven { "skipping driven electrodes" } else { "all pairs" };
        Protocol::from_quads0(
            format!(
                "skip-{skip} drive and measurement {variant}: {} measurements of {electrode_count} electrodes",
                quads.len()
            ),
            electrode_count,
            &quads,
        )
    }

    /// A protocol from 1-based quads `[drive+, drive−, measure+, measure−]`, one per
    /// measurement, 1 A: each distinct drive pair becomes one stimulation, in order of first use.
    pub fn from_quads(
        description: impl Into<String>,
        electrode_count: usize,
        quads: &[[usize; 4]],
    ) -> Result<Protocol, ProtocolError> {
        let mut zero_based = Vec::with_capacity(quads.len());
        for (row, q) in quads.iter().enumerate() {
            for &e in q {
                if e == 0 || e > electrode_count {
                    return Err(ProtocolError::NoSuchElectrode { row: row + 1, electrode: e, count: electrode_count });
                }
            }
            zero_based.push(q.map(|e| e - 1));
        }
        Protocol::from_quads0(description.into(), electrode_count, &zero_based)
    }

    fn from_quads0(description: String, l: usize, quads: &[[usize; 4]]) -> Result<Protocol, ProtocolError> {
        let mut drives: Vec<[usize; 2]> = Vec::new();
        let mut measurements = Vec::with_capacity(quads.len());
        for (row, &[dp, dm, mp, mm]) in quads.iter().enumerate() {
            if dp == dm || mp == mm {
                let electrode = if dp == dm { dp } else { mp };
                return Err(ProtocolError::SamePair { row: row + 1, electrode: electrode + 1 });
            }
            let stimulation = match drives.iter().position(|d| *d == [dp, dm]) {
                Some(i) => i,
                None => {
                    drives.push([dp, dm]);
                    drives.len() - 1
                }
            };
            let mut weights = vec![0.0; l];
            weights[mp] = 1.0;
            weights[mm] = -1.0;
            measurements.push(Measurement { stimulation, weights });
        }
        let stimulations = drives
            .iter()
            .map(|&[p, m]| {
                let mut current = vec![0.0; l];
                current[p] = 1.0;
                current[m] = -1.0;
                current
            })
            .collect();
        Protocol::new(description, l, stimulations, measurements)
    }

    /// A one-line description, e.g. "two-terminal, all 120 pairs of 16 electrodes".
    pub fn description(&self) -> &str {
        &self.description
    }

    /// Number of electrodes L.
    pub fn electrode_count(&self) -> usize {
        self.electrode_count
    }

    /// The stimulations: current per electrode, in A.
    pub fn stimulations(&self) -> &[Vec<f64>] {
        &self.stimulations
    }

    /// The measurements, in frame order.
    pub fn measurements(&self) -> &[Measurement] {
        &self.measurements
    }

    /// Number of measurements in one frame.
    pub fn len(&self) -> usize {
        self.measurements.len()
    }

    /// Whether the protocol has no measurement (never true for a constructed protocol).
    pub fn is_empty(&self) -> bool {
        self.measurements.is_empty()
    }
}

/// 0-based quads `[drive+, drive−, measure+, measure−]`: for k = 0 … L−1, drive +1 A at
/// k + `drive_offset`, −1 A at k; for m = 0 … L−1, measure U_m − U_{m + measure_offset}
/// (indices modulo L), leaving out pairs that share an electrode with the drive if `skip_driven`.
fn drive_and_measure_quads(l: usize, drive_offset: usize, measure_offset: usize, skip_driven: bool) -> Vec<[usize; 4]> {
    let mut quads = Vec::new();
    for k in 0..l {
        let (minus, plus) = (k, (k + drive_offset) % l);
        for m in 0..l {
            let (a, b) = (m, (m + measure_offset) % l);
            let touches = [a, b].iter().any(|e| *e == minus || *e == plus);
            if skip_driven && touches {
                continue;
            }
            quads.push([plus, minus, a, b]);
        }
    }
    quads
}

/// Refuses more electrodes than a sensor may have, before any pattern is made.
fn check_electrode_count(electrodes: usize) -> Result<(), ProtocolError> {
    let max = MAX_ELECTRODES;
    if electrodes > max {
        return Err(ProtocolError::TooManyElectrodes { electrodes, max });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pair(m: &Measurement) -> (usize, usize) {
        let plus = m.weights.iter().position(|w| *w == 1.0).unwrap_or(99);
        let minus = m.weights.iter().position(|w| *w == -1.0).unwrap_or(99);
        (plus, minus)
    }

    #[test]
    fn two_terminal_has_120_pairs_in_lexicographic_order() {
        let p = Protocol::two_terminal(16).unwrap();
        assert_eq!(p.len(), 120);
        assert_eq!(p.stimulations().len(), 120);
        assert_eq!(pair(&p.measurements()[0]), (0, 1));
        assert_eq!(pair(&p.measurements()[14]), (0, 15));
        assert_eq!(pair(&p.measurements()[15]), (1, 2));
        assert_eq!(pair(&p.measurements()[119]), (14, 15));
        for m in p.measurements() {
            assert_eq!(p.stimulations()[m.stimulation], m.weights, "drive pair is the measured pair");
        }
    }

    #[test]
    fn adjacent_variants_have_208_and_256_measurements() {
        let skip = Protocol::adjacent(16, true).unwrap();
        assert_eq!(skip.len(), 208);
        assert_eq!(Protocol::adjacent(16, false).unwrap().len(), 256);
        // Stimulation 0: −1 A at electrode 0, +1 A at 1; first kept pair is (2, 3).
        assert_eq!(skip.stimulations()[0][..3], [-1.0, 1.0, 0.0]);
        assert_eq!(pair(&skip.measurements()[0]), (2, 3));
        assert_eq!(pair(&skip.measurements()[12]), (14, 15));
        assert_eq!(Protocol::opposite(16).unwrap().stimulations()[3][11], 1.0);
    }

    /// The 1-based quads `[drive+, drive−, measure+, measure−]` of each measurement.
    fn quads(p: &Protocol) -> Vec<[usize; 4]> {
        p.measurements()
            .iter()
            .map(|m| {
                let s = &p.stimulations()[m.stimulation];
                let plus = s.iter().position(|c| *c == 1.0).unwrap_or(99);
                let minus = s.iter().position(|c| *c == -1.0).unwrap_or(99);
                let (a, b) = pair(m);
                [plus + 1, minus + 1, a + 1, b + 1]
            })
            .collect()
    }

    #[test]
    fn skip_protocols_count_and_start_as_documented() {
        // Skip 0 is adjacent, pattern for pattern.
        assert_eq!(
            Protocol::skip(16, 0, true).unwrap().measurements(),
            Protocol::adjacent(16, true).unwrap().measurements()
        );
        assert_eq!(
            Protocol::skip(16, 0, false).unwrap().stimulations(),
            Protocol::adjacent(16, false).unwrap().stimulations()
        );
        let skip2 = Protocol::skip(16, 2, true).unwrap();
        assert_eq!(skip2.len(), 208);
        assert_eq!(
            skip2.description(),
            "skip-2 drive and measurement skipping driven electrodes: 208 measurements of 16 electrodes"
        );
        // Drive −1 A at 1, +1 A at 4; pairs (m, m+3) from m = 1 without 1, 4 or 14 (= 1 − 3).
        assert_eq!(quads(&skip2)[..3], [[4, 1, 2, 5], [4, 1, 3, 6], [4, 1, 5, 8]]);
        assert_eq!(quads(&skip2)[12], [4, 1, 16, 3]);
        assert_eq!(quads(&skip2)[13], [5, 2, 1, 4]);
        assert_eq!(Protocol::skip(16, 2, false).unwrap().len(), 256);
        assert_eq!(Protocol::skip(16, 7, true).unwrap().len(), 224);
        assert_eq!(Protocol::skip(32, 0, true).unwrap().len(), 928);
        assert_eq!(Protocol::skip(32, 2, true).unwrap().len(), 928);
        assert_eq!(Protocol::skip(16, 14, true).unwrap().len(), 208);
        assert_eq!(Protocol::skip(16, 15, true).unwrap_err(), ProtocolError::SkipTooLarge { skip: 15, electrodes: 16 });
        assert_eq!(
            Protocol::skip(16, 15, true).unwrap_err().to_string(),
            "skip-15 pairs electrode k with k + 16, which needs more than 16 electrodes; use a skip of at most 14"
        );
    }

    /// The OpenEIT firmware's tables (`OpenEIT/EIT_Firmware`, `lookup.h`, 2018), first rows,
    /// 0-based as there. The 32-electrode adjacent table lists {A−, A+, V−, V+} as the firmware
    /// wires them (`ImpedanceMeasurement_EIT32_4WireBioIsolated.c`: M1 = A−, M2 = A+, M3 = V−,
    /// M4 = V+); the 16-electrode opposition table lists {A+, A−, V+, V−} on the 32-way
    /// multiplexer's even channels (electrode = channel / 2).
    #[test]
    fn openeit_firmware_orders_are_adjacent_and_opposite() {
        let adjacent_32: [[usize; 4]; 32] = [
            [0, 1, 2, 3],
            [0, 1, 3, 4],
            [0, 1, 4, 5],
            [0, 1, 5, 6],
            [0, 1, 6, 7],
            [0, 1, 7, 8],
            [0, 1, 8, 9],
            [0, 1, 9, 10],
            [0, 1, 10, 11],
            [0, 1, 11, 12],
            [0, 1, 12, 13],
            [0, 1, 13, 14],
            [0, 1, 14, 15],
            [0, 1, 15, 16],
            [0, 1, 16, 17],
            [0, 1, 17, 18],
            [0, 1, 18, 19],
            [0, 1, 19, 20],
            [0, 1, 20, 21],
            [0, 1, 21, 22],
            [0, 1, 22, 23],
            [0, 1, 23, 24],
            [0, 1, 24, 25],
            [0, 1, 25, 26],
            [0, 1, 26, 27],
            [0, 1, 27, 28],
            [0, 1, 28, 29],
            [0, 1, 29, 30],
            [0, 1, 30, 31],
            [1, 2, 3, 4],
            [1, 2, 4, 5],
            [1, 2, 5, 6],
        ];
        let tail_32: [[usize; 4]; 3] = [[2, 3, 31, 0], [31, 0, 1, 2], [31, 0, 29, 30]];
        let p = Protocol::adjacent(32, true).unwrap();
        assert_eq!(p.len(), 928);
        let q = quads(&p);
        // Ours is [A+, A−, +, −] with U_m − U_{m+1}: the firmware's {A−, A+, V−, V+} is [2, 1, 3, 4] of it.
        let as_firmware = |r: [usize; 4]| [r[1] - 1, r[0] - 1, r[2] - 1, r[3] - 1];
        for (row, want) in adjacent_32.iter().enumerate() {
            assert_eq!(as_firmware(q[row]), *want, "row {row}");
        }
        for (row, want) in [(86, tail_32[0]), (899, tail_32[1]), (927, tail_32[2])] {
            assert_eq!(as_firmware(q[row]), want, "row {row}");
        }
        let opposition_16: [[usize; 4]; 14] = [
            [0, 16, 4, 2],
            [0, 16, 6, 4],
            [0, 16, 8, 6],
            [0, 16, 10, 8],
            [0, 16, 12, 10],
            [0, 16, 14, 12],
            [0, 16, 20, 18],
            [0, 16, 22, 20],
            [0, 16, 24, 22],
            [0, 16, 26, 24],
            [0, 16, 28, 26],
            [0, 16, 30, 28],
            [2, 18, 6, 4],
            [2, 18, 8, 6],
        ];
        let tail_16: [[usize; 4]; 3] = [[2, 18, 0, 30], [4, 20, 2, 0], [30, 14, 28, 26]];
        let p = Protocol::opposite(16).unwrap();
        assert_eq!(p.len(), 192);
        let q = quads(&p);
        // The firmware drives +1 A at its A+ and reads V+ − V−; ours flips both, so the value is the same.
        let as_firmware = |r: [usize; 4]| [2 * (r[1] - 1), 2 * (r[0] - 1), 2 * (r[3] - 1), 2 * (r[2] - 1)];
        for (row, want) in opposition_16.iter().enumerate() {
            assert_eq!(as_firmware(q[row]), *want, "row {row}");
        }
        for (row, want) in [(23, tail_16[0]), (24, tail_16[1]), (191, tail_16[2])] {
            assert_eq!(as_firmware(q[row]), want, "row {row}");
        }
    }

    #[test]
    fn more_electrodes_than_a_sensor_has_are_refused_before_any_pattern_is_made() {
        let max = MAX_ELECTRODES;
        for protocol in
            [Protocol::two_terminal(100_000), Protocol::adjacent(100_000, true), Protocol::opposite(max + 1)]
        {
            assert!(
                matches!(protocol, Err(ProtocolError::TooManyElectrodes { max: m, .. }) if m == max),
                "{protocol:?}"
            );
        }
    }

    #[test]
    fn bad_patterns_are_named() {
        let err = Protocol::new("x", 3, vec![vec![1.0, 0.0, 0.0]], vec![]).unwrap_err();
        assert!(matches!(err, ProtocolError::Empty { .. }));
        let m = Measurement { stimulation: 0, weights: vec![1.0, -1.0, 0.0] };
        let err = Protocol::new("x", 3, vec![vec![1.0, 0.0, 0.0]], vec![m.clone()]).unwrap_err();
        assert_eq!(
            err.to_string(),
            "stimulation 1 sums to 1, not 0: currents must be conserved and measurements must be differences"
        );
        let err =
            Protocol::new("x", 3, vec![vec![1.0, -1.0, 0.0]], vec![Measurement { stimulation: 1, ..m }]).unwrap_err();
        assert_eq!(err, ProtocolError::NoSuchStimulation { index: 1, stimulation: 2, count: 1 });
        let err = Protocol::from_quads("q", 16, &[[1, 2, 3, 4], [1, 17, 3, 4]]).unwrap_err();
        assert_eq!(err.to_string(), "row 2 names electrode 17, but electrodes are numbered 1 to 16");
        let err = Protocol::from_quads("q", 16, &[[1, 2, 3, 3]]).unwrap_err();
        assert_eq!(err, ProtocolError::SamePair { row: 1, electrode: 3 });
    }

    /// A stimulation of no current, a measurement of no weight, and currents or weights past
    /// their bound are refused, naming which (1-based); they gave values of 0 or 1e300 Ω.
    #[test]
    fn empty_and_huge_patterns_are_refused() {
        let m = |stimulation, weights: [f64; 3]| Measurement { stimulation, weights: weights.to_vec() };
        let new = |stimulations: Vec<[f64; 3]>, measurements| {
            Protocol::new("x", 3, stimulations.iter().map(|s| s.to_vec()).collect(), measurements)
        };
        let drive = [1.0, -1.0, 0.0];
        let err = new(vec![drive, [0.0; 3]], vec![m(0, [0.0, 1.0, -1.0])]).unwrap_err();
        assert_eq!(err.to_string(), "stimulation 2 drives no current: every electrode's current is 0 A");
        let err = new(vec![drive], vec![m(0, [0.0, 1.0, -1.0]), m(0, [0.0; 3])]).unwrap_err();
        assert_eq!(err.to_string(), "measurement 2 weighs no electrode: every weight is 0");
        let err = new(vec![[0.0, 1e300, -1e300]], vec![m(0, [0.0, 1.0, -1.0])]).unwrap_err();
        assert_eq!(
            err.to_string(),
            "stimulation 1 puts a current of 1e300 A on electrode 2: past ±1e3 A, more than any board uses"
        );
        let err = new(vec![drive], vec![m(0, [0.0, 1.0, -1.0]), m(0, [-2e3, 1e3, 1e3])]).unwrap_err();
        assert_eq!(
            err,
            ProtocolError::TooLarge { what: "measurement", index: 2, electrode: 1, value: -2e3, max: MAX_WEIGHT }
        );
        // At the bounds they stand.
        assert!(new(vec![[MAX_CURRENT, -MAX_CURRENT, 0.0]], vec![m(0, [0.0, MAX_WEIGHT, -MAX_WEIGHT])]).is_ok());
    }
}
