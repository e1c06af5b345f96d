//! The sensor spec: outline, electrodes, protocol and mesh density, in SI units.
//!
//! [`SensorSpec::square_hydrogel`] is the paper's sensor. A spec is plain data;
//! [`SensorSpec::validate`] checks it and every constructor below checks it first, naming the
//! spec key (as written in the TOML file) and the reason when something is wrong.

use thiserror::Error;

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
        /// The value found (SI units).
        value: f64,
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
    #[error("`electrodes.positions`: electrode {electrode} is {distance} m from the boundary; put it on the outline")]
    PositionOffBoundary {
        /// 1-based electrode.
        electrode: usize,
        /// Distance to the boundary, in m.
        distance: f64,
    },
    /// An electrode is wider than the side it sits on.
    #[error("`electrodes.width` = {width} m is wider than side {side} ({side_length} m) of the rectangle")]
    WiderThanSide {
        /// Electrode width, in m.
        width: f64,
        /// 1-based side (1 bottom, 2 right, 3 top, 4 left).
        side: usize,
        /// Side length, in m.
        side_length: f64,
    },
    /// Two electrodes overlap on the boundary.
    #[error("electrodes {first} and {second} overlap: their centres are {gap} m apart along the boundary but `electrodes.width` is {width} m")]
    Overlap {
        /// 1-based first electrode.
        first: usize,
        /// 1-based second electrode.
        second: usize,
        /// Arc distance between their centres, in m.
        gap: f64,
        /// Electrode width, in m.
        width: f64,
    },
    /// The protocol could not be built.
    #[error("`protocol` does not make a protocol")]
    Protocol(#[from] ProtocolError),
    /// Meshing failed.
    #[error("the outline could not be meshed")]
    Mesh(#[from] MeshError),
    /// The forward model could not be built.
    #[error("the forward model could not be built")]
    Forward(#[from] ForwardError),
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

    /// The unit's symbol, "m" or "mm".
    pub fn symbol(self) -> &'static str {
        match self {
            LengthUnit::Metre => "m",
            LengthUnit::Millimetre => "mm",
        }
    }
}

/// Where electrodes sit on the boundary.
#[derive(Debug, Clone, PartialEq)]
pub enum Placement {
    /// Rectangles: count/4 per side, centred in equal parts of each side, electrode 1 first on
    /// the bottom side from the left corner, counter-clockwise.
    PerSide,
    /// Circles: equal spacing, electrode 1 centred at `start_angle_deg`, counter-clockwise.
    Equal {
        /// Angle of electrode 1's centre from the +x axis, in degrees.
        start_angle_deg: f64,
    },
    /// Any outline: electrode centres at these points (m), projected onto the boundary.
    Explicit {
        /// Centre of each electrode `[x, y]`, in m, in electrode order.
        positions: Vec<[f64; 2]>,
    },
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
    /// Complete electrodes (default) or ideal point electrodes.
    pub point: bool,
}

/// Which protocol the board runs.
#[derive(Debug, Clone, PartialEq)]
pub enum ProtocolSpec {
    /// All pairs, driven and measured on the same pair (the paper's; 120 for L = 16).
    TwoTerminal,
    /// Adjacent drive and measurement, skipping pairs that touch a driven electrode (208).
    Adjacent,
    /// Adjacent drive and measurement keeping every pair (256).
    AdjacentAll,
    /// Opposite drive, adjacent measurement.
    Opposite,
    /// Patterns read from a file.
    Custom(Protocol),
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
    /// How finely to mesh.
    pub mesh: MeshParams,
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
                point: false,
            },
            protocol: ProtocolSpec::TwoTerminal,
            mesh: MeshParams::default(),
        }
    }

    /// Checks every value; the error names the spec key at fault.
    pub fn validate(&self) -> Result<(), SpecError> {
        self.electrode_positions().map(|_| ())
    }

    /// The electrodes as arc-length intervals of the boundary, after checking the whole spec.
    pub fn electrode_positions(&self) -> Result<Vec<Electrode>, SpecError> {
        positive("thickness", self.thickness)?;
        positive("conductivity", self.conductivity)?;
        self.check_outline()?;
        self.check_mesh()?;
        let e = &self.electrodes;
        if e.count < 2 {
            return Err(SpecError::ElectrodeCount { count: e.count, reason: "at least 2 electrodes are needed" });
        }
        if !e.point {
            positive("electrodes.width", e.width)?;
            positive("electrodes.contact_impedance", e.contact_impedance)?;
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
                return Err(SpecError::Overlap { first, second, gap, width });
            }
        }
        Ok(electrodes)
    }

    fn electrode_centres(&self, width: f64) -> Result<Vec<f64>, SpecError> {
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
                        return Err(SpecError::WiderThanSide { width, side: side + 1, side_length: len });
                    }
                    for k in 0..per_side {
                        centres.push(start + (k as f64 + 0.5) * len / per_side as f64);
                    }
                    start += len;
                }
                Ok(centres)
            }
            (Placement::Equal { start_angle_deg }, Outline::Circle { radius }) => Ok((0..count)
                .map(|k| {
                    (radius * start_angle_deg.to_radians() + k as f64 * perimeter / count as f64).rem_euclid(perimeter)
                })
                .collect()),
            (Placement::Explicit { positions }, outline) => {
                if positions.len() != count {
                    return Err(SpecError::PositionCount { expected: count, got: positions.len() });
                }
                positions
                    .iter()
                    .enumerate()
                    .map(|(k, &p)| {
                        let (s, distance) = outline.locate(p);
                        if distance > 1e-3 * perimeter {
                            return Err(SpecError::PositionOffBoundary { electrode: k + 1, distance });
                        }
                        Ok(s)
                    })
                    .collect()
            }
            (Placement::PerSide, outline) => Err(SpecError::Placement {
                placement: "per-side",
                outline: outline_kind(outline),
                hint: "per-side is for rectangles; use \"explicit\" positions",
            }),
            (Placement::Equal { .. }, outline) => Err(SpecError::Placement {
                placement: "equal",
                outline: outline_kind(outline),
                hint: "equal spacing is for circles; use \"explicit\" positions",
            }),
        }
    }

    fn check_outline(&self) -> Result<(), SpecError> {
        match &self.outline {
            Outline::Rectangle { width, height } => {
                positive("outline.width", *width)?;
                positive("outline.height", *height)
            }
            Outline::Circle { radius } => positive("outline.radius", *radius),
            Outline::Polygon { points } => {
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
        positive("mesh.triangles", m.triangles as f64)?;
        if let Some(h) = m.max_element_size {
            positive("mesh.max_element_size", h)?;
        }
        positive("mesh.grading", m.grading)?;
        positive("mesh.min_angle_deg", m.min_angle_deg)
    }

    /// The protocol the spec asks for.
    pub fn protocol(&self) -> Result<Protocol, SpecError> {
        let l = self.electrodes.count;
        Ok(match &self.protocol {
            ProtocolSpec::TwoTerminal => Protocol::two_terminal(l)?,
            ProtocolSpec::Adjacent => Protocol::adjacent(l, true)?,
            ProtocolSpec::AdjacentAll => Protocol::adjacent(l, false)?,
            ProtocolSpec::Opposite => Protocol::opposite(l)?,
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

fn positive(key: &'static str, value: f64) -> Result<(), SpecError> {
    if value > 0.0 && value.is_finite() {
        Ok(())
    } else {
        Err(SpecError::NotPositive { key, value })
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
