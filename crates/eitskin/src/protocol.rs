//! Stimulation and measurement patterns, as data.
//!
//! A [`Protocol`] is a list of stimulations (the current through each electrode, in A; they
//! sum to zero) and a list of measurements (a stimulation index and a weight per electrode;
//! the weights sum to zero, so a measurement is a voltage difference, in V). Electrodes are
//! indexed from 0 here and numbered from 1 in files and messages.

use thiserror::Error;

/// What is wrong with a protocol; indices in messages are 1-based, as a user counts.
#[derive(Debug, Error, PartialEq)]
pub enum ProtocolError {
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
    /// A quad drives or measures between an electrode and itself.
    #[error("row {row} pairs electrode {electrode} with itself")]
    SamePair {
        /// 1-based row of the quad list.
        row: usize,
        /// The electrode (1-based).
        electrode: usize,
    },
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

    /// Adjacent drive, adjacent measurement (EIDORS `mk_stim_patterns(L,1,[0,1],[0,1],…)`):
    /// stimulation k puts −1 A at k and +1 A at k+1; measurement m is U_m − U_{m+1}.
    /// With `skip_driven` the pairs touching a driven electrode are left out (L(L−3) = 208
    /// for L = 16); without, all L² = 256 are kept.
    pub fn adjacent(electrode_count: usize, skip_driven: bool) -> Result<Protocol, ProtocolError> {
        Protocol::drive_and_adjacent_measure(electrode_count, 1, skip_driven, "adjacent")
    }

    /// Opposite drive (−1 A at k, +1 A at k + L/2), adjacent measurements that skip the driven
    /// electrodes; L stimulations.
    pub fn opposite(electrode_count: usize) -> Result<Protocol, ProtocolError> {
        Protocol::drive_and_adjacent_measure(electrode_count, electrode_count / 2, true, "opposite")
    }

    fn drive_and_adjacent_measure(
        l: usize,
        offset: usize,
        skip_driven: bool,
        name: &str,
    ) -> Result<Protocol, ProtocolError> {
        let mut quads = Vec::new();
        for k in 0..l {
            let (minus, plus) = (k, (k + offset) % l);
            for m in 0..l {
                let (a, b) = (m, (m + 1) % l);
                let touches = [a, b].iter().any(|e| *e == minus || *e == plus);
                if skip_driven && touches {
                    continue;
                }
                quads.push([plus, minus, a, b]);
            }
        }
        let variant = if skip_driven { "skipping driven electrodes" } else { "all pairs" };
        Protocol::from_quads0(
            format!("{name} drive, adjacent measurement {variant}: {} measurements of {l} electrodes", quads.len()),
            l,
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
}
