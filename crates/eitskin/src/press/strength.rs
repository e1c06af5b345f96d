//! A touch's strength: the number a calibration curve s(F) = a·e^(−F/b) + c turns into force,
//! and the place its unit is looked up at.
//!
//! Every force method of the study is one [`Strength`] on a [`PseudoArray`](crate::pseudo_array::PseudoArray)
//! (the paper's 5×5, a finer one, or one unit for the whole sheet): the same function,
//! [`Strength::read`], gives the value when calibrating, when validating, and on the frame path.
//!
//! | strength | value | unit looked up at | needs |
//! |---|---|---|---|
//! | [`Strength::Peak`] | the image's peak, S/m (the paper's) | touch centre | — |
//! | [`Strength::FittedDrop`] | drop of the press fitted to Δv, at the indenter's radius (0 if none fits) | press centre | [`PressModel`](crate::press_fit::PressModel) |
//! | [`Strength::SizedDrop`] | the same, every press's radius fitted too | press centre | [`PressModel`](crate::press_fit::PressModel) |
//! | [`Strength::Sensitivity`] | peak ÷ S(centre), S(x) the peak of a reference press there | touch centre | [`ContrastMap`] |
//! | [`Strength::ContrastPeak`] | the drop whose simulated peak at the centre is the peak | touch centre | [`ContrastMap`] |
//! | [`Strength::ContrastVolume`] | the same from the touch's volume | touch centre | [`ContrastMap`] |
//! | [`Strength::ContrastPeakAndVolume`] | the mean of the two | touch centre | [`ContrastMap`] |
//!
//! ```
//! use eitskin::strength::Strength;
//! assert_eq!(Strength::from_name("fitted drop"), Some(Strength::FittedDrop));
//! assert!(Strength::ALL.iter().all(|s| Strength::from_name(s.name()) == Some(*s)));
//! assert!(Strength::ContrastVolume.needs_contrast_map() && !Strength::Peak.needs_press_model());
//! ```
//!
//! Not for: fitting curves (that is [`calibration`](crate::calibration)).

use crate::contrast_map::ContrastMap;
use crate::press_fit::PressFit;
use crate::touch::Touch;

/// What a calibration's curves take as the touch's strength.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Strength {
    /// The peak of the touch's image, in S/m (the paper's).
    #[default]
    Peak,
    /// The drop of the press fitted to Δv ([`crate::press_fit`]), a fraction of the background,
    /// as a press of the indenter's radius ([`PressFit::equivalent_drop`](crate::press_fit::PressFit::equivalent_drop));
    /// its unit is looked up at the fitted centre.
    FittedDrop,
    /// [`Strength::FittedDrop`] with every press's radius fitted, not only where the misfit asks
    /// for it ([`PressModel::with_every_radius`](crate::press_fit::PressModel::with_every_radius)):
    /// less biased for presses wider or narrower than the indenter, noisier for those of its size.
    SizedDrop,
    /// The peak divided by the sensitivity S(x) at the touch's centre (dimensionless): the
    /// continuous calibration.
    Sensitivity,
    /// The drop (fraction of the background) that explains the peak at the touch's centre, read
    /// off the [`ContrastMap`].
    ContrastPeak,
    /// The drop that explains the touch's volume at its centre, read off the [`ContrastMap`].
    ContrastVolume,
    /// The mean of [`Strength::ContrastPeak`] and [`Strength::ContrastVolume`].
    ContrastPeakAndVolume,
}

/// Where a touch's unit is looked up, and its strength there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reading {
    /// The point whose unit the touch belongs to, in m.
    pub centre: [f64; 2],
    /// The strength, in the unit of its [`Strength`].
    pub value: f64,
    /// Its standard deviation from the measurement noise, in the same unit; `None` where it is
    /// not known (a press fitted to Δv whitened by the measured noise knows it).
    pub std: Option<f64>,
}

impl Strength {
    /// Every strength, the paper's first.
    pub const ALL: [Strength; 7] = [
        Strength::Peak,
        Strength::FittedDrop,
        Strength::SizedDrop,
        Strength::Sensitivity,
        Strength::ContrastPeak,
        Strength::ContrastVolume,
        Strength::ContrastPeakAndVolume,
    ];

    /// Its name in calibration files and on the command line, e.g. `"fitted drop"`.
    pub fn name(self) -> &'static str {
        match self {
            Strength::Peak => "peak",
            Strength::FittedDrop => "fitted drop",
            Strength::SizedDrop => "sized drop",
            Strength::Sensitivity => "peak / sensitivity",
            Strength::ContrastPeak => "contrast map (peak)",
            Strength::ContrastVolume => "contrast map (volume)",
            Strength::ContrastPeakAndVolume => "contrast map (peak and volume)",
        }
    }

    /// The strength of that [`Strength::name`].
    pub fn from_name(name: &str) -> Option<Strength> {
        Strength::ALL.into_iter().find(|s| s.name() == name)
    }

    /// The unit of its values: `"S/m"` for the peak, `"1"` for the dimensionless ones.
    pub fn unit(self) -> &'static str {
        match self {
            Strength::Peak => "S/m",
            _ => "1",
        }
    }

    /// Whether reading it needs the press fitted to Δv.
    pub fn needs_press_model(self) -> bool {
        matches!(self, Strength::FittedDrop | Strength::SizedDrop)
    }

    /// Whether reading it needs the forward model's contrast map.
    pub fn needs_contrast_map(self) -> bool {
        matches!(
            self,
            Strength::Sensitivity | Strength::ContrastPeak | Strength::ContrastVolume | Strength::ContrastPeakAndVolume
        )
    }

    /// The reading of `touch`, with the press fitted from it and its model's indenter radius in
    /// m (`None`: none fitted) and the contrast map; `None` when this strength needs a contrast
    /// map and none is given.
    pub fn read(self, touch: &Touch, press: Option<(&PressFit, f64)>, map: Option<&ContrastMap>) -> Option<Reading> {
        let at = touch.centre;
        let value = match self {
            Strength::Peak => touch.peak,
            // A touch with nothing in Δv that looks like a press has no drop.
            Strength::FittedDrop | Strength::SizedDrop => {
                return Some(press.map_or(Reading { centre: at, value: 0.0, std: None }, |(p, indenter)| Reading {
                    centre: p.centre,
                    value: p.equivalent_drop(indenter),
                    std: p.equivalent_drop_std,
                }))
            }
            Strength::Sensitivity => touch.peak / map?.sensitivity(at),
            Strength::ContrastPeak => map?.drop(touch.peak, at, false),
            Strength::ContrastVolume => map?.drop(touch.volume, at, true),
            Strength::ContrastPeakAndVolume => {
                let map = map?;
                0.5 * (map.drop(touch.peak, at, false) + map.drop(touch.volume, at, true))
            }
        };
        Some(Reading { centre: at, value, std: None })
    }
}

impl std::fmt::Display for Strength {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}
