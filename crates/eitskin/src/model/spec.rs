//! The sensor spec: outline, electrodes, protocol and mesh density, in SI units.
//!
//! [`SensorSpec::square_hydrogel`] is the paper's sensor. A spec is plain data;
//! [`SensorSpec::validate`] checks it and every constructor below checks it first, naming the
//! spec key (as written in the TOML file) and the reason when something is wrong.

use thiserror::Error;

use crate::conductivity::{conductivity_in_range, CONDUCTIVITY_RANGE};
use crate::forward::{ElectrodeModel, ForwardError, ForwardModel};
use crate::geometry::{first_crossing, signed_area, Electrode, Outline};
use crate::mesh::{Mesh, MeshError, MeshParams};
use crate::protocol::{Protocol, ProtocolError};

/// What is wrong with a spec, naming the key as written in the spec file; lengths in m.
#[derive(Debug, Error, PartialEq)]
pub enum SpecError {
    /// A value that must be positive is not.
    #[error("`{key}` must be a positive number, got {value}")]
    NotPositive {
        /// The spec key, e.g. `electrodes.contact_impedance`.
        key: &'static str,
        /// The value found, in the spec's units.
        value: Quantity,
    },
    /// A point whose coordinates are not both finite numbers.
    #[error(
        "`{key}`: point {point} is ({}, {}); both coordinates must be finite numbers within ±{}",
        unit.quote(*x), unit.quote(*y), unit.quote(MAX_LENGTH)
    )]
    NotFinitePoint {
        /// `outline.points` or `electrodes.positions`.
        key: &'static str,
        /// 1-based point.
        point: usize,
        /// Its x, in m.
        x: f64,
        /// Its y, in m.
        y: f64,
        /// The unit the spec gives lengths in, which the message quotes them in.
        unit: LengthUnit,
    },
    /// A polygon needs three corners.
    #[error("`outline.points` needs at least 3 points, got {got}")]
    TooFewPoints {
        /// Points given.
        got: usize,
    },
    /// Two polygon edges cross or touch.
    #[error("`outline.points`: edge {first} crosses edge {second} (edge k joins point k to point k+1, counting from 1); the outline must be a simple polygon")]
    SelfCrossing {
        /// 1-based first edge.
        first: usize,
        /// 1-based second edge.
        second: usize,
    },
    /// Polygon points go clockwise.
    #[error("`outline.points` run clockwise; list them counter-clockwise")]
    Clockwise,
    /// Too few electrodes, or a count the placement cannot share out.
    #[error("`electrodes.count` = {count}: {reason}")]
    ElectrodeCount {
        /// The count given.
        count: usize,
        /// Why it does not work.
        reason: &'static str,
    },
    /// A placement that does not fit the outline.
    #[error("`electrodes.placement` = \"{placement}\" does not fit a {outline} outline; {hint}")]
    Placement {
        /// The placement given.
        placement: &'static str,
        /// The outline kind.
        outline: &'static str,
        /// What to use instead.
        hint: &'static str,
    },
    /// Explicit placement needs one position per electrode.
    #[error("`electrodes.positions` has {got} points for {expected} electrodes")]
    PositionCount {
        /// `electrodes.count`.
        expected: usize,
        /// Positions given.
        got: usize,
    },
    /// An explicit position is far from the boundary.
    #[error("`electrodes.positions`: electrode {electrode} is {distance} from the boundary; put it on the outline")]
    PositionOffBoundary {
        /// 1-based electrode.
        electrode: usize,
        /// Distance to the boundary, in the spec's length unit.
        distance: Quantity,
    },
    /// An electrode is wider than the side it sits on.
    #[error("`electrodes.width` = {width} is wider than side {side} ({side_length}) of the rectangle")]
    WiderThanSide {
        /// Electrode width, in the spec's length unit.
        width: Quantity,
        /// 1-based side (1 bottom, 2 right, 3 top, 4 left).
        side: usize,
        /// Side length, in the spec's length unit.
        side_length: Quantity,
    },
    /// Two electrodes overlap on the boundary.
    #[error("electrodes {first} and {second} overlap: their centres are {gap} apart along the boundary but `electrodes.width` is {width}")]
    Overlap {
        /// 1-based first electrode.
        first: usize,
        /// 1-based second electrode.
        second: usize,
        /// Arc distance between their centres, in the spec's length unit.
        gap: Quantity,
        /// Electrode width, in the spec's length unit.
        width: Quantity,
    },
    /// A number outside its allowed range, or not finite.
    #[error("`{key}` must be a finite number within {range}, got {value}")]
    OutOfRange {
        /// The spec key, e.g. `electrodes.start_angle_deg`.
        key: &'static str,
        /// The value found, in the spec's units.
        value: Quantity,
        /// The allowed range, with its unit, e.g. "[-360, 360] degrees".
        range: String,
    },
    /// `electrodes.numbering` = "clockwise" with explicit positions, which are already in order.
    #[error("`electrodes.numbering` = \"clockwise\" does not apply to placement = \"explicit\": the positions are already listed in electrode order; list them in the order the board numbers them")]
    NumberingWithExplicit,
    /// The ray from the centre at `electrodes.start_angle_deg` misses the outline.
    #[error("`electrodes.start_angle_deg` = {angle_deg}: the ray from the origin at this angle does not meet the outline; centre the polygon on the origin")]
    StartAngleMisses {
        /// The angle given, in degrees.
        angle_deg: f64,
    },
    /// A dropped channel or electrode that the protocol does not have.
    #[error("`{key}` names {value}, but they are numbered 1 to {count}")]
    MaskOutOfRange {
        /// `protocol.drop_channels` or `protocol.drop_electrodes`.
        key: &'static str,
        /// The 1-based number given.
        value: usize,
        /// How many there are.
        count: usize,
    },
    /// The dropped channels and electrodes leave no measurement.
    #[error("`protocol.drop_channels` and `protocol.drop_electrodes` leave none of the {measurements} measurements")]
    MaskDropsAll {
        /// Measurements of the protocol.
        measurements: usize,
    },
    /// The protocol could not be built.
    #[error("`protocol` does not make a protocol")]
    Protocol(#[from] ProtocolError),
    /// Meshing failed.
    #[error("the outline could not be meshed")]
    Mesh(#[from] MeshError),
    /// The sensor's mount on a robot (`mount.*`) is not one.
    #[error("`{key}` = {value}: {reason}")]
    Mount {
        /// The spec key, e.g. `mount.orientation`.
        key: &'static str,
        /// The value as written (lengths in the spec's unit).
        value: String,
        /// What it must be.
        reason: &'static str,
    },
    /// The forward model could not be built.
    #[error("the forward model could not be built")]
    Forward(#[from] ForwardError),
}

/// The shortest length a spec takes (thickness, sizes, widths), in m: 1 µm.
pub const MIN_LENGTH: f64 = 1e-6;

/// The longest length a spec takes, and the largest coordinate of a point, in m: 1 km.
pub const MAX_LENGTH: f64 = 1e3;

/// The least contact impedance a complete electrode takes, in Ω·m²: far below any electrode's
/// (1e-4 is a gel electrode's order); below it, against a sheet of the least conductivity, the
/// model's matrix loses its positive pivots to rounding.
pub const MIN_CONTACT_IMPEDANCE: f64 = 1e-9;

/// The largest contact impedance a complete electrode takes, in Ω·m²: an electrode barely
/// touching the sheet.
pub const MAX_CONTACT_IMPEDANCE: f64 = 1e3;

/// [`MIN_CONTACT_IMPEDANCE`] to [`MAX_CONTACT_IMPEDANCE`] as messages state the range.
pub const CONTACT_IMPEDANCE_RANGE: &str = "[1e-9, 1e3] Ω·m²";

/// The most triangles `mesh.triangles` takes.
pub const MAX_TRIANGLES: usize = 100_000_000;

/// The most electrodes `electrodes.count` takes (a protocol's limit).
pub use crate::protocol::MAX_ELECTRODES;

/// A number in a message, in the unit the user gave it in: a value as written shows to 15
/// significant figures (so that 15.7 mm converted to metres and back reads 15.7 mm, not
/// 15.699999999999998), a value derived from others to 4.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Quantity {
    /// The number, in `unit`.
    pub value: f64,
    /// The unit's symbol ("mm", "S/m"); empty for a pure number.
    pub unit: &'static str,
    /// Significant figures shown.
    pub figures: usize,
}

impl Quantity {
    /// A value as the user wrote it, in `unit`.
    pub fn written(value: f64, unit: &'static str) -> Quantity {
        Quantity { value, unit, figures: 15 }
    }

    /// A value derived from what the user wrote, in `unit`.
    pub fn derived(value: f64, unit: &'static str) -> Quantity {
        Quantity { value, unit, figures: 4 }
    }
}

impl std::fmt::Display for Quantity {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        // Rounded through scientific notation, then shown in the shortest form that reads back.
        let rounded: f64 = format!("{:.*e}", self.figures.saturating_sub(1), self.value).parse().unwrap_or(self.value);
        let number = match rounded.abs() {
            x if x != 0.0 && x.is_finite() && !(1e-6..1e15).contains(&x) => format!("{rounded:e}"),
            _ => format!("{rounded}"),
        };
        match self.unit {
            _ if !rounded.is_finite() => write!(f, "{number}"),
            "" => write!(f, "{number}"),
            unit => write!(f, "{number} {unit}"),
        }
    }
}

/// The unit that lengths in the spec file and in outputs are given in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LengthUnit {
    /// Metres.
    Metre,
    /// Millimetres.
    #[default]
    Millimetre,
}

impl LengthUnit {
    /// Metres per unit.
    pub fn metres(self) -> f64 {
        match self {
            LengthUnit::Metre => 1.0,
            LengthUnit::Millimetre => 1e-3,
        }
    }

    /// `metres` in this unit, as written, for a message.
    pub fn quote(self, metres: f64) -> Quantity {
        Quantity::written(metres / self.metres(), self.symbol())
    }

    /// The unit's symbol, "m" or "mm".
    pub fn symbol(self) -> &'static str {
        match self {
            LengthUnit::Metre => "m",
            LengthUnit::Millimetre => "mm",
        }
    }
}

/// Where electrodes sit on the boundary; [`Numbering`] says which way they are counted.
#[derive(Debug, Clone, PartialEq)]
pub enum Placement {
    /// Rectangles: count/4 per side, centred in equal parts of each side, electrode 1 first on
    /// the bottom side from the left corner (numbered counter-clockwise; clockwise keeps
    /// electrode 1 there and counts up the left side).
    PerSide,
    /// Any outline: centres equally spaced by arc length along the boundary, electrode 1
    /// centred where the ray from the origin at `start_angle_deg` meets the boundary.
    Equal {
        /// Angle of the ray to electrode 1's centre, from the +x axis counter-clockwise, in
        /// degrees, within [−360, 360].
        start_angle_deg: f64,
    },
    /// Any outline: electrode centres at these points (m), in electrode order, projected onto
    /// the boundary (the numbering is the order given: only counter-clockwise applies).
    Explicit {
        /// Centre of each electrode `[x, y]`, in m, in electrode order.
        positions: Vec<[f64; 2]>,
    },
}

/// Which way electrode numbers run around the boundary, seen from above (+z).
///
/// A placement defines the counter-clockwise layout; clockwise keeps electrode 1 where it is
/// and numbers the rest the other way, so clockwise electrode k (1-based) sits where
/// counter-clockwise electrode (2 − k) mod L sits (L for 0).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Numbering {
    /// Electrode 2 follows electrode 1 counter-clockwise (EIDORS', and this crate's, default).
    #[default]
    CounterClockwise,
    /// Electrode 2 follows electrode 1 clockwise (pyEIT's circle, the OpenEIT dashboard).
    Clockwise,
}

impl Numbering {
    /// The spec file's name: "counter-clockwise" or "clockwise".
    pub fn name(self) -> &'static str {
        match self {
            Numbering::CounterClockwise => "counter-clockwise",
            Numbering::Clockwise => "clockwise",
        }
    }

    /// The numbering named as in the spec file, if it is one.
    pub fn from_name(name: &str) -> Option<Numbering> {
        match name {
            "counter-clockwise" => Some(Numbering::CounterClockwise),
            "clockwise" => Some(Numbering::Clockwise),
            _ => None,
        }
    }

    /// Reorders counter-clockwise electrode centres (arc lengths, m) into this numbering.
    pub fn apply(self, mut centres: Vec<f64>) -> Vec<f64> {
        if self == Numbering::Clockwise && centres.len() > 1 {
            centres[1..].reverse();
        }
        centres
    }
}

/// The electrodes of a sensor.
#[derive(Debug, Clone, PartialEq)]
pub struct ElectrodeSpec {
    /// Number of electrodes L.
    pub count: usize,
    /// Length along the boundary, in m (ignored for point electrodes).
    pub width: f64,
    /// Contact impedance, in Ω·m² (ignored for point electrodes).
    pub contact_impedance: f64,
    /// Where they sit.
    pub placement: Placement,
    /// Which way they are numbered.
    pub numbering: Numbering,
    /// Complete electrodes (default) or ideal point electrodes.
    pub point: bool,
}

/// Which protocol the board runs; the orders are given in [`crate::protocol`].
#[derive(Debug, Clone, PartialEq)]
pub enum ProtocolSpec {
    /// `two-terminal`: all pairs, driven and measured on the same pair (the paper's; 120 for L = 16).
    TwoTerminal,
    /// `adjacent`: adjacent drive and measurement, skipping pairs that touch a driven electrode (208).
    Adjacent,
    /// `adjacent-all`: adjacent drive and measurement keeping every pair (256).
    AdjacentAll,
    /// `opposite`: opposite drive, adjacent measurement, skipping driven electrodes (192).
    Opposite,
    /// `skip-S` / `skip-S-all`: drive (k, k+S+1), measure (m, m+S+1), see [`Protocol::skip`].
    Skip {
        /// Electrodes S between the two of a pair (0 is adjacent).
        skip: usize,
        /// Leave out the pairs that share an electrode with the drive (`skip-S`, not `skip-S-all`).
        skip_driven: bool,
    },
    /// Patterns read from a file.
    Custom(Protocol),
}

impl ProtocolSpec {
    /// The built-in protocol names, for help texts and error messages.
    pub const NAMES: &'static str =
        "two-terminal, adjacent, adjacent-all, opposite, skip-S, skip-S-all (S = 0, 1, 2, …)";

    /// The built-in protocol of this name (as in `protocol.kind` and `--protocol`), if any.
    pub fn from_name(name: &str) -> Option<ProtocolSpec> {
        match name {
            "two-terminal" => return Some(ProtocolSpec::TwoTerminal),
            "adjacent" => return Some(ProtocolSpec::Adjacent),
            "adjacent-all" => return Some(ProtocolSpec::AdjacentAll),
            "opposite" => return Some(ProtocolSpec::Opposite),
            _ => {}
        }
        let rest = name.strip_prefix("skip-")?;
        let (digits, skip_driven) = match rest.strip_suffix("-all") {
            Some(digits) => (digits, false),
            None => (rest, true),
        };
        if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
            return None;
        }
        Some(ProtocolSpec::Skip { skip: digits.parse().ok()?, skip_driven })
    }

    /// The name [`ProtocolSpec::from_name`] reads back; "custom" for patterns from a file.
    pub fn name(&self) -> String {
        match self {
            ProtocolSpec::TwoTerminal => "two-terminal".into(),
            ProtocolSpec::Adjacent => "adjacent".into(),
            ProtocolSpec::AdjacentAll => "adjacent-all".into(),
            ProtocolSpec::Opposite => "opposite".into(),
            ProtocolSpec::Skip { skip, skip_driven: true } => format!("skip-{skip}"),
            ProtocolSpec::Skip { skip, skip_driven: false } => format!("skip-{skip}-all"),
            ProtocolSpec::Custom(_) => "custom".into(),
        }
    }
}

/// Channels left out of every image, as a board's known faults: measurements by number, and
/// every measurement whose stimulation drives, or whose pattern reads, a broken electrode
/// (0-based here; 1-based in the spec file).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ChannelMask {
    /// Dropped measurements, 0-based, in protocol order.
    pub channels: Vec<usize>,
    /// Broken electrodes, 0-based.
    pub electrodes: Vec<usize>,
}

/// A sensor: outline, thickness, background conductivity, electrodes, protocol, mesh density.
#[derive(Debug, Clone, PartialEq)]
pub struct SensorSpec {
    /// The unit lengths are written in, in files and outputs (values here are always in m).
    pub length_unit: LengthUnit,
    /// Sheet thickness, in m.
    pub thickness: f64,
    /// Background conductivity, in S/m.
    pub conductivity: f64,
    /// The sheet's shape, centred on the origin.
    pub outline: Outline,
    /// The electrodes.
    pub electrodes: ElectrodeSpec,
    /// The stimulation and measurement protocol.
    pub protocol: ProtocolSpec,
    /// Channels the board never measures well, left out of every image.
    pub mask: ChannelMask,
    /// How finely to mesh.
    pub mesh: MeshParams,
    /// Where the sensor sits on a robot (its frame's name and pose on a link), if said.
    pub mount: Option<crate::mount::Mount>,
}

impl Default for SensorSpec {
    fn default() -> Self {
        SensorSpec::square_hydrogel()
    }
}

impl SensorSpec {
    /// The paper's sensor: 200 × 200 mm, 10 mm thick, 1 S/m, 16 electrodes 10 mm wide, four a
    /// side, contact impedance 1e-4 Ω·m², two-terminal protocol, about 4,000 triangles.
    pub fn square_hydrogel() -> SensorSpec {
        SensorSpec {
            length_unit: LengthUnit::Millimetre,
            thickness: 0.010,
            conductivity: 1.0,
            outline: Outline::Rectangle { width: 0.200, height: 0.200 },
            electrodes: ElectrodeSpec {
                count: 16,
                width: 0.010,
                contact_impedance: 1e-4,
                placement: Placement::PerSide,
                numbering: Numbering::CounterClockwise,
                point: false,
            },
            protocol: ProtocolSpec::TwoTerminal,
            mask: ChannelMask::default(),
            mesh: MeshParams::default(),
            mount: None,
        }
    }

    /// Checks every value, the protocol and its mask included; the error names the spec key at fault.
    pub fn validate(&self) -> Result<(), SpecError> {
        self.electrode_positions()?;
        if let Some(mount) = &self.mount {
            mount.check(self.length_unit)?;
        }
        self.used_channels()?;
        Ok(())
    }

    /// Which measurements of the protocol are used (true) after [`SensorSpec::mask`]: a
    /// dropped channel, or one whose stimulation drives or whose pattern reads a dropped electrode.
    pub fn used_channels(&self) -> Result<Vec<bool>, SpecError> {
        let protocol = self.protocol()?;
        let (count, electrodes) = (protocol.measurements().len(), protocol.electrode_count());
        let check = |key, list: &[usize], count| match list.iter().find(|&&i| i >= count) {
            Some(&i) => Err(SpecError::MaskOutOfRange { key, value: i + 1, count }),
            None => Ok(()),
        };
        check("protocol.drop_channels", &self.mask.channels, count)?;
        check("protocol.drop_electrodes", &self.mask.electrodes, electrodes)?;
        let touches =
            |m: &crate::Measurement, e: usize| protocol.stimulations()[m.stimulation][e] != 0.0 || m.weights[e] != 0.0;
        let used: Vec<bool> = protocol
            .measurements()
            .iter()
            .enumerate()
            .map(|(i, m)| !self.mask.channels.contains(&i) && !self.mask.electrodes.iter().any(|&e| touches(m, e)))
            .collect();
        if !used.contains(&true) {
            return Err(SpecError::MaskDropsAll { measurements: count });
        }
        Ok(used)
    }

    /// The electrodes as arc-length intervals of the boundary, after checking the whole spec.
    pub fn electrode_positions(&self) -> Result<Vec<Electrode>, SpecError> {
        self.length_within("thickness", self.thickness)?;
        let conductivity = Quantity::written(self.conductivity, "S/m");
        positive("conductivity", conductivity)?;
        within("conductivity", conductivity, conductivity_in_range, CONDUCTIVITY_RANGE)?;
        self.check_outline()?;
        self.check_mesh()?;
        let e = &self.electrodes;
        if e.count < 2 {
            return Err(SpecError::ElectrodeCount { count: e.count, reason: "at least 2 electrodes are needed" });
        }
        if e.count > MAX_ELECTRODES {
            return Err(SpecError::ElectrodeCount { count: e.count, reason: "at most 256 electrodes are taken" });
        }
        if !e.point {
            self.length_within("electrodes.width", e.width)?;
            let impedance = Quantity::written(e.contact_impedance, "Ω·m²");
            positive("electrodes.contact_impedance", impedance)?;
            let in_range = |z: f64| (MIN_CONTACT_IMPEDANCE..=MAX_CONTACT_IMPEDANCE).contains(&z);
            within("electrodes.contact_impedance", impedance, in_range, CONTACT_IMPEDANCE_RANGE)?;
        }
        let width = if e.point { 0.0 } else { e.width };
        let perimeter = self.outline.perimeter();
        let centres = self.electrode_centres(width)?;
        let electrodes: Vec<Electrode> = centres.iter().map(|&centre| Electrode { centre, width }).collect();
        let mut order: Vec<usize> = (0..electrodes.len()).collect();
        order.sort_by(|&a, &b| electrodes[a].centre.total_cmp(&electrodes[b].centre));
        for k in 0..order.len() {
            let (a, b) = (order[k], order[(k + 1) % order.len()]);
            let gap = (electrodes[b].centre - electrodes[a].centre).rem_euclid(perimeter);
            let gap = if order.len() == 2 { gap.min(perimeter - gap) } else { gap };
            if gap <= width || gap < 1e-9 * perimeter {
                let (first, second) = (a.min(b) + 1, a.max(b) + 1);
                return Err(SpecError::Overlap {
                    first,
                    second,
                    gap: self.length(gap, Quantity::derived),
                    width: self.length(width, Quantity::written),
                });
            }
        }
        Ok(electrodes)
    }

    fn electrode_centres(&self, width: f64) -> Result<Vec<f64>, SpecError> {
        let counter_clockwise = self.counter_clockwise_centres(width)?;
        match (&self.electrodes.placement, self.electrodes.numbering) {
            (Placement::Explicit { .. }, Numbering::Clockwise) => Err(SpecError::NumberingWithExplicit),
            (_, numbering) => Ok(numbering.apply(counter_clockwise)),
        }
    }

    /// Centres (arc lengths, m) in the placement's counter-clockwise order.
    fn counter_clockwise_centres(&self, width: f64) -> Result<Vec<f64>, SpecError> {
        let count = self.electrodes.count;
        let perimeter = self.outline.perimeter();
        match (&self.electrodes.placement, &self.outline) {
            (Placement::PerSide, Outline::Rectangle { width: w, height: h }) => {
                if !count.is_multiple_of(4) {
                    return Err(SpecError::ElectrodeCount {
                        count,
                        reason: "per-side placement needs a multiple of 4",
                    });
                }
                let per_side = count / 4;
                let sides = [*w, *h, *w, *h];
                let mut centres = Vec::with_capacity(count);
                let mut start = 0.0;
                for (side, &len) in sides.iter().enumerate() {
                    if width > len {
                        return Err(SpecError::WiderThanSide {
                            width: self.length(width, Quantity::written),
                            side: side + 1,
                            side_length: self.length(len, Quantity::written),
                        });
                    }
                    for k in 0..per_side {
                        centres.push(start + (k as f64 + 0.5) * len / per_side as f64);
                    }
                    start += len;
                }
                Ok(centres)
            }
            (Placement::Equal { start_angle_deg }, outline) => {
                let angle_deg = *start_angle_deg;
                if !(angle_deg.is_finite() && (-360.0..=360.0).contains(&angle_deg)) {
                    return Err(SpecError::OutOfRange {
                        key: "electrodes.start_angle_deg",
                        value: Quantity::written(angle_deg, "degrees"),
                        range: "[-360, 360] degrees".to_string(),
                    });
                }
                let first = outline.arc_length_at_angle(angle_deg).ok_or(SpecError::StartAngleMisses { angle_deg })?;
                Ok((0..count).map(|k| (first + k as f64 * perimeter / count as f64).rem_euclid(perimeter)).collect())
            }
            (Placement::Explicit { positions }, outline) => {
                if positions.len() != count {
                    return Err(SpecError::PositionCount { expected: count, got: positions.len() });
                }
                self.finite_points("electrodes.positions", positions)?;
                positions
                    .iter()
                    .enumerate()
                    .map(|(k, &p)| {
                        let (s, distance) = outline.locate(p);
                        if distance > 1e-3 * perimeter {
                            let distance = self.length(distance, Quantity::derived);
                            return Err(SpecError::PositionOffBoundary { electrode: k + 1, distance });
                        }
                        Ok(s)
                    })
                    .collect()
            }
            (Placement::PerSide, outline) => Err(SpecError::Placement {
                placement: "per-side",
                outline: outline_kind(outline),
                hint: "per-side is for rectangles; use \"equal\" spacing or \"explicit\" positions",
            }),
        }
    }

    fn check_outline(&self) -> Result<(), SpecError> {
        match &self.outline {
            Outline::Rectangle { width, height } => {
                self.length_within("outline.width", *width)?;
                self.length_within("outline.height", *height)
            }
            Outline::Circle { radius } => self.length_within("outline.radius", *radius),
            Outline::Polygon { points } => {
                self.finite_points("outline.points", points)?;
                if points.len() < 3 {
                    return Err(SpecError::TooFewPoints { got: points.len() });
                }
                if let Some((a, b)) = first_crossing(points) {
                    return Err(SpecError::SelfCrossing { first: a + 1, second: b + 1 });
                }
                if signed_area(points) <= 0.0 {
                    return Err(SpecError::Clockwise);
                }
                Ok(())
            }
        }
    }

    fn check_mesh(&self) -> Result<(), SpecError> {
        let m = &self.mesh;
        let between = |(lo, hi): (f64, f64)| move |v: f64| v >= lo && v <= hi;
        let triangles = Quantity::written(m.triangles as f64, "");
        within("mesh.triangles", triangles, between((1.0, MAX_TRIANGLES as f64)), "[1, 100000000]")?;
        if let Some(h) = m.max_element_size {
            self.length_within("mesh.max_element_size", h)?;
        }
        within("mesh.grading", Quantity::written(m.grading, ""), between((1e-3, 1.0)), "[0.001, 1]")?;
        // Ruppert refinement is not known to end above about 33.9°; spade stops and says so.
        let angle = Quantity::written(m.min_angle_deg, "degrees");
        within("mesh.min_angle_deg", angle, between((f64::MIN_POSITIVE, 33.0)), "(0, 33] degrees")
    }

    /// `metres` in the spec's length unit, as `kind` quotes it.
    fn length(&self, metres: f64, kind: fn(f64, &'static str) -> Quantity) -> Quantity {
        kind(metres / self.length_unit.metres(), self.length_unit.symbol())
    }

    fn finite_points(&self, key: &'static str, points: &[[f64; 2]]) -> Result<(), SpecError> {
        let within = |c: f64| c.is_finite() && c.abs() <= MAX_LENGTH;
        match points.iter().position(|p| !(within(p[0]) && within(p[1]))) {
            Some(k) => Err(SpecError::NotFinitePoint {
                key,
                point: k + 1,
                x: points[k][0],
                y: points[k][1],
                unit: self.length_unit,
            }),
            None => Ok(()),
        }
    }

    /// Refuses a length (m) outside [`MIN_LENGTH`, `MAX_LENGTH`], quoting it and the range in
    /// the spec's unit.
    fn length_within(&self, key: &'static str, metres: f64) -> Result<(), SpecError> {
        if (MIN_LENGTH..=MAX_LENGTH).contains(&metres) {
            return Ok(());
        }
        let [lo, hi] = [MIN_LENGTH, MAX_LENGTH].map(|l| self.length(l, Quantity::written).to_string());
        Err(SpecError::OutOfRange {
            key,
            value: self.length(metres, Quantity::written),
            range: format!("[{lo}, {hi}]"),
        })
    }

    /// The protocol the spec asks for.
    pub fn protocol(&self) -> Result<Protocol, SpecError> {
        let l = self.electrodes.count;
        Ok(match &self.protocol {
            ProtocolSpec::TwoTerminal => Protocol::two_terminal(l)?,
            ProtocolSpec::Adjacent => Protocol::adjacent(l, true)?,
            ProtocolSpec::AdjacentAll => Protocol::adjacent(l, false)?,
            ProtocolSpec::Opposite => Protocol::opposite(l)?,
            ProtocolSpec::Skip { skip, skip_driven } => Protocol::skip(l, *skip, *skip_driven)?,
            ProtocolSpec::Custom(p) => p.clone(),
        })
    }

    /// How the forward model treats the electrodes.
    pub fn electrode_model(&self) -> ElectrodeModel {
        if self.electrodes.point {
            ElectrodeModel::Point
        } else {
            ElectrodeModel::Complete {
                contact_impedance: vec![self.electrodes.contact_impedance; self.electrodes.count],
            }
        }
    }

    /// About how many triangles [`SensorSpec::mesh`] will make: `mesh.triangles`, or the
    /// outline's area over an equilateral triangle of `mesh.max_element_size` when that is set.
    pub fn expected_triangles(&self) -> f64 {
        match self.mesh.max_element_size {
            Some(h) => self.outline.area() / (3f64.sqrt() / 4.0 * h * h),
            None => self.mesh.triangles as f64,
        }
    }

    /// The fewest triangles [`SensorSpec::mesh`] makes on this sheet, however few
    /// `mesh.triangles` asks for (about: near it the count moves a little either way): the
    /// outline's corners and the electrodes' ends are nodes, the mesh is graded toward the
    /// electrodes' edges (`mesh.grading`) and no angle is under `mesh.min_angle_deg`.
    pub fn fewest_triangles(&self) -> Result<usize, SpecError> {
        let mut coarsest = self.clone();
        coarsest.mesh.triangles = 1;
        coarsest.mesh.max_element_size = None;
        Ok(coarsest.mesh()?.triangles().len())
    }

    /// Meshes the sheet as the spec says.
    pub fn mesh(&self) -> Result<Mesh, SpecError> {
        let electrodes = self.electrode_positions()?;
        Ok(Mesh::generate(&self.outline, &electrodes, &self.mesh)?)
    }

    /// Mesh, protocol and forward model for this spec, ready to solve.
    pub fn forward_model(&self) -> Result<ForwardModel, SpecError> {
        self.forward_model_on(self.mesh()?)
    }

    /// The forward model on a given mesh (e.g. another tool's), with this spec's electrodes,
    /// thickness and protocol.
    pub fn forward_model_on(&self, mesh: Mesh) -> Result<ForwardModel, SpecError> {
        self.validate()?;
        Ok(ForwardModel::new(mesh, self.electrode_model(), self.thickness, self.protocol()?)?)
    }

    /// One conductivity per triangle of `mesh`: the background, in S/m.
    pub fn homogeneous(&self, mesh: &Mesh) -> Vec<f64> {
        vec![self.conductivity; mesh.triangles().len()]
    }
}

/// Every point of `points` finite: a NaN corner passes every comparison the geometry makes
/// (no crossing, no orientation), and the mesher's triangulation then never ends.
fn positive(key: &'static str, value: Quantity) -> Result<(), SpecError> {
    if value.value > 0.0 && value.value.is_finite() {
        Ok(())
    } else {
        Err(SpecError::NotPositive { key, value })
    }
}

/// Refuses a `value` of `key` for which `in_range` does not hold, stating `range` (with its unit).
fn within(key: &'static str, value: Quantity, in_range: impl Fn(f64) -> bool, range: &str) -> Result<(), SpecError> {
    if in_range(value.value) {
        Ok(())
    } else {
        Err(SpecError::OutOfRange { key, value, range: range.to_string() })
    }
}

fn outline_kind(outline: &Outline) -> &'static str {
    match outline {
        Outline::Rectangle { .. } => "rectangle",
        Outline::Circle { .. } => "circle",
        Outline::Polygon { .. } => "polygon",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const PI_3: f64 = std::f64::consts::PI / 3.0;

    #[test]
    fn paper_square_places_electrode_one_bottom_left_counter_clockwise() {
        let spec = SensorSpec::square_hydrogel();
        let e = spec.electrode_positions().unwrap();
        let p = |k: usize| spec.outline.point_at(e[k].centre);
        let close = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).abs() < 1e-12 && (a[1] - b[1]).abs() < 1e-12;
        assert!(close(p(0), [-0.075, -0.1]));
        assert!(close(p(4), [0.1, -0.075]));
        assert!(close(p(8), [0.075, 0.1]));
        assert!(close(p(15), [-0.1, -0.075]));
    }

    fn points(spec: &SensorSpec) -> Vec<[f64; 2]> {
        spec.electrode_positions().unwrap().iter().map(|e| spec.outline.point_at(e.centre)).collect()
    }

    fn with(outline: Outline, placement: Placement, numbering: Numbering) -> SensorSpec {
        let paper = SensorSpec::square_hydrogel();
        SensorSpec { outline, electrodes: ElectrodeSpec { placement, numbering, ..paper.electrodes }, ..paper }
    }

    /// A value the user wrote in millimetres reads back as written, not with the float noise of
    /// its trip through metres.
    #[test]
    fn quantities_read_as_written_in_the_users_unit() {
        let metres = 15.7 * LengthUnit::Millimetre.metres();
        let back = metres / LengthUnit::Millimetre.metres();
        assert_eq!(back.to_string(), "15.699999999999998", "the noise this guards against");
        assert_eq!(Quantity::written(back, "mm").to_string(), "15.7 mm");
        assert_eq!(Quantity::derived(std::f64::consts::PI * 2.5, "mm").to_string(), "7.854 mm");
        assert_eq!(Quantity::written(-1e-4, "Ω·m²").to_string(), "-0.0001 Ω·m²");
        assert_eq!(Quantity::written(f64::NAN, "mm").to_string(), "NaN");
        assert_eq!(Quantity::written(3.0, "").to_string(), "3");
        assert_eq!(Quantity::written(1e300, "m").to_string(), "1e300 m");
        assert_eq!(Quantity::written(-0.11549012178846248, "m").to_string(), "-0.115490121788462 m");
    }

    /// A corner or an electrode that is not a finite number is named before any geometry is
    /// built (a NaN corner used to send the mesher's triangulation into a loop).
    #[test]
    fn a_point_that_is_not_finite_is_named() {
        let square: Vec<[f64; 2]> = vec![[-0.1, -0.1], [0.1, -0.1], [0.1, 0.1], [-0.1, 0.1]];
        let mut corners = square.clone();
        corners[2] = [f64::NAN, 0.1];
        let equal = Placement::Equal { start_angle_deg: 0.0 };
        let spec = with(Outline::Polygon { points: corners }, equal, Numbering::CounterClockwise);
        let error = spec.mesh().unwrap_err();
        assert_eq!(
            error.to_string(),
            "`outline.points`: point 3 is (NaN, 100 mm); both coordinates must be finite numbers within ±1000000 mm"
        );
        let mut positions: Vec<[f64; 2]> = (0..16).map(|k| [-0.1 + 0.0125 * k as f64, -0.1]).collect();
        positions[15] = [0.05, f64::INFINITY];
        let outline = Outline::Polygon { points: square };
        let spec = with(outline, Placement::Explicit { positions }, Numbering::CounterClockwise);
        assert!(matches!(spec.mesh(), Err(SpecError::NotFinitePoint { key: "electrodes.positions", point: 16, .. })));
    }

    #[test]
    fn clockwise_keeps_electrode_one_and_reverses_the_rest() {
        let square = Outline::Rectangle { width: 0.2, height: 0.2 };
        let hexagon = Outline::Polygon {
            points: (0..6).map(|k| [0.1 * (k as f64 * PI_3).cos(), 0.1 * (k as f64 * PI_3).sin()]).collect(),
        };
        for (outline, placement) in [
            (square.clone(), Placement::PerSide),
            (square, Placement::Equal { start_angle_deg: -100.0 }),
            (Outline::Circle { radius: 0.1 }, Placement::Equal { start_angle_deg: 180.0 }),
            (hexagon, Placement::Equal { start_angle_deg: 30.0 }),
        ] {
            let ccw = points(&with(outline.clone(), placement.clone(), Numbering::CounterClockwise));
            let cw = points(&with(outline, placement, Numbering::Clockwise));
            let l = ccw.len();
            for k in 1..=l {
                // 1-based: clockwise electrode k is counter-clockwise electrode (2 − k) mod L.
                let j = (2 + l - k) % l;
                let j = if j == 0 { l } else { j };
                assert_eq!(cw[k - 1], ccw[j - 1], "electrode {k}");
            }
        }
        // The paper's square numbered clockwise: electrode 2 is the lowest on the left side.
        let cw =
            points(&with(Outline::Rectangle { width: 0.2, height: 0.2 }, Placement::PerSide, Numbering::Clockwise));
        let close = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).abs() < 1e-12 && (a[1] - b[1]).abs() < 1e-12;
        assert!(close(cw[0], [-0.075, -0.1]) && close(cw[1], [-0.1, -0.075]), "{cw:?}");
    }

    #[test]
    fn equal_spacing_on_rectangle_and_polygon_starts_at_the_angle_and_spaces_arc_lengths() {
        let pentagon =
            Outline::Polygon { points: vec![[-0.1, -0.08], [0.12, -0.1], [0.1, 0.05], [0.0, 0.12], [-0.11, 0.06]] };
        for (outline, angle, first) in [
            (Outline::Rectangle { width: 0.3, height: 0.2 }, 90.0, [0.0, 0.1]),
            (Outline::Rectangle { width: 0.3, height: 0.2 }, 180.0, [-0.15, 0.0]),
            (Outline::Rectangle { width: 0.2, height: 0.2 }, 45.0, [0.1, 0.1]),
            (pentagon.clone(), 90.0, [0.0, 0.12]),
            (pentagon, 270.0, [0.0, -0.08 - 0.02 * 0.1 / 0.22]),
        ] {
            let spec = with(outline.clone(), Placement::Equal { start_angle_deg: angle }, Numbering::CounterClockwise);
            let e = spec.electrode_positions().unwrap();
            let p0 = outline.point_at(e[0].centre);
            assert!((p0[0] - first[0]).abs() < 1e-12 && (p0[1] - first[1]).abs() < 1e-12, "{p0:?} ≠ {first:?}");
            let step = outline.perimeter() / e.len() as f64;
            for k in 0..e.len() {
                let gap = (e[(k + 1) % e.len()].centre - e[k].centre).rem_euclid(outline.perimeter());
                assert!((gap - step).abs() < 1e-12, "gap {k}: {gap} ≠ {step}");
            }
        }
    }

    #[test]
    fn bad_numbering_and_angles_name_the_key() {
        let circle = Outline::Circle { radius: 0.1 };
        for angle in [f64::NAN, f64::INFINITY, 400.0, -360.5] {
            let spec = with(circle.clone(), Placement::Equal { start_angle_deg: angle }, Numbering::CounterClockwise);
            let err = spec.validate().unwrap_err();
            assert!(matches!(err, SpecError::OutOfRange { key: "electrodes.start_angle_deg", .. }), "{err}");
            assert!(err
                .to_string()
                .starts_with("`electrodes.start_angle_deg` must be a finite number within [-360, 360] degrees"));
        }
        let off = Outline::Polygon { points: vec![[0.1, 0.1], [0.2, 0.1], [0.2, 0.2], [0.1, 0.2]] };
        let spec = with(off, Placement::Equal { start_angle_deg: 0.0 }, Numbering::CounterClockwise);
        assert_eq!(spec.validate().unwrap_err(), SpecError::StartAngleMisses { angle_deg: 0.0 });
        let centres = points(&SensorSpec::square_hydrogel());
        let square = Outline::Rectangle { width: 0.2, height: 0.2 };
        let spec = with(square, Placement::Explicit { positions: centres }, Numbering::Clockwise);
        let err = spec.validate().unwrap_err();
        assert_eq!(err, SpecError::NumberingWithExplicit);
        assert!(err.to_string().contains("`electrodes.numbering`"), "{err}");
        assert_eq!(Numbering::from_name("anticlockwise"), None);
        for n in [Numbering::Clockwise, Numbering::CounterClockwise] {
            assert_eq!(Numbering::from_name(n.name()), Some(n));
        }
    }

    /// Conductivity, contact impedance and thickness are checked against their stated ranges
    /// when the spec is read, naming the key and quoting the value (a conductivity of 1e-300
    /// S/m reached the solver, which said the mesh might not be connected).
    #[test]
    fn conductivity_impedance_and_thickness_have_ranges() {
        let message = |change: fn(&mut SensorSpec)| {
            let mut spec = SensorSpec::square_hydrogel();
            change(&mut spec);
            spec.validate().unwrap_err().to_string()
        };
        assert_eq!(
            message(|s| s.conductivity = 1e-300),
            "`conductivity` must be a finite number within [1e-6, 1e6] S/m, got 1e-300 S/m"
        );
        assert_eq!(
            message(|s| s.conductivity = 2e6),
            "`conductivity` must be a finite number within [1e-6, 1e6] S/m, got 2000000 S/m"
        );
        assert_eq!(message(|s| s.conductivity = 0.0), "`conductivity` must be a positive number, got 0 S/m");
        assert_eq!(
            message(|s| s.electrodes.contact_impedance = 1e-20),
            "`electrodes.contact_impedance` must be a finite number within [1e-9, 1e3] Ω·m², got 1e-20 Ω·m²"
        );
        assert_eq!(
            message(|s| s.electrodes.contact_impedance = 1e9),
            "`electrodes.contact_impedance` must be a finite number within [1e-9, 1e3] Ω·m², got 1000000000 Ω·m²"
        );
        assert_eq!(
            message(|s| s.thickness = 1e-300),
            "`thickness` must be a finite number within [0.001 mm, 1000000 mm], got 1e-297 mm"
        );
        // The ends of each range stand, and solve.
        for (sigma, z) in [(1e-6, 1e-9), (1e6, 1e3), (1e-6, 1e3), (1e6, 1e-9)] {
            let mut spec = SensorSpec::square_hydrogel();
            (spec.conductivity, spec.electrodes.contact_impedance, spec.mesh.triangles) = (sigma, z, 300);
            let model = spec.forward_model().unwrap();
            let values = model.measure(&spec.homogeneous(model.mesh())).unwrap();
            assert!(values.iter().all(|v| v.is_finite() && *v > 0.0), "σ = {sigma}, z = {z}");
        }
    }

    /// However few triangles are asked for, the mesher makes at least the fewest it can.
    #[test]
    fn the_fewest_triangles_are_what_one_asked_triangle_gives() {
        let spec = SensorSpec::square_hydrogel();
        let fewest = spec.fewest_triangles().unwrap();
        assert!((100..1000).contains(&fewest), "{fewest}");
        for asked in [2, 50] {
            let mut s = spec.clone();
            s.mesh.triangles = asked;
            assert_eq!(s.mesh().unwrap().triangles().len(), fewest, "{asked}");
        }
    }

    #[test]
    fn protocol_names_read_back() {
        for name in ["two-terminal", "adjacent", "adjacent-all", "opposite", "skip-0", "skip-2", "skip-15-all"] {
            assert_eq!(ProtocolSpec::from_name(name).map(|p| p.name()).as_deref(), Some(name));
        }
        assert_eq!(ProtocolSpec::from_name("skip-3"), Some(ProtocolSpec::Skip { skip: 3, skip_driven: true }));
        for bad in ["skip-", "skip--1", "skip-+2", "skip-2-al", "skip-x", "adjacent-skip", "custom", ""] {
            assert_eq!(ProtocolSpec::from_name(bad), None, "{bad}");
        }
    }

    #[test]
    fn a_mask_drops_channels_and_every_measurement_of_a_broken_electrode() {
        let mut spec = SensorSpec::square_hydrogel(); // two-terminal: 120 pairs, (1,2) … (15,16)
        spec.mask = ChannelMask { channels: vec![0, 119], electrodes: vec![0] };
        let used = spec.used_channels().unwrap();
        // Electrode 1 is in 15 pairs, channel 1 among them; channel 120 is (15, 16).
        assert_eq!(used.iter().filter(|u| !**u).count(), 16);
        assert!(!used[0] && !used[14] && used[15] && !used[119]);
        spec.mask = ChannelMask { channels: vec![120], electrodes: vec![] };
        let err = spec.validate().unwrap_err();
        assert_eq!(err.to_string(), "`protocol.drop_channels` names 121, but they are numbered 1 to 120");
        spec.mask = ChannelMask { channels: vec![], electrodes: (0..15).collect() };
        assert!(matches!(spec.validate(), Err(SpecError::MaskDropsAll { measurements: 120 })));
    }

    #[test]
    fn circle_equal_spacing_starts_at_the_angle() {
        let spec = SensorSpec {
            outline: Outline::Circle { radius: 1.0 },
            electrodes: ElectrodeSpec {
                placement: Placement::Equal { start_angle_deg: 90.0 },
                width: 0.1,
                ..SensorSpec::square_hydrogel().electrodes
            },
            ..SensorSpec::square_hydrogel()
        };
        let e = spec.electrode_positions().unwrap();
        let p0 = spec.outline.point_at(e[0].centre);
        let p4 = spec.outline.point_at(e[4].centre);
        assert!(p0[0].abs() < 1e-12 && (p0[1] - 1.0).abs() < 1e-12);
        assert!((p4[0] + 1.0).abs() < 1e-12 && p4[1].abs() < 1e-12, "counter-clockwise: {p4:?}");
    }
}
