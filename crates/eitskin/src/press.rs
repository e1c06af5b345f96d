//! Touches to presses and forces: the press fit, the strengths a force is read from, the contrast
//! map, the pseudo-array, the calibration and the learned calibration.

pub mod calibration;
pub mod contrast_map;
pub mod learn;
pub mod press_fit;
pub mod pseudo_array;
pub mod strength;
