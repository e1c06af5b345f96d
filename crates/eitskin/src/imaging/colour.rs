//! The one colour map of every image eitskin draws — the CLI's figures, the live viewer and
//! Python's plots — and its sign convention: blue where the conductivity fell (a press on the
//! gel), red where it rose, the same |change| the same strength of colour on either side.
//!
//! It is ColorBrewer's diverging RdBu, reversed (matplotlib's `"RdBu_r"`): eleven stops evenly
//! spaced from u = −1 to u = +1, linear between them. Drawn on a scale symmetric about 0, a
//! value v shows as [`colour`]`(v / scale)`.
//!
//! ```
//! use eitskin::colour::{colour, COLOUR_STOPS};
//! assert_eq!(colour(-1.0), COLOUR_STOPS[0]); // dark blue: the strongest decrease
//! assert_eq!(colour(0.0), [247, 247, 247]);  // near white: no change
//! assert!(colour(-0.5)[2] > colour(-0.5)[0] && colour(0.5)[0] > colour(0.5)[2]);
//! ```

/// The map's stops from u = −1 (first) to u = +1 (last), sRGB, evenly spaced.
pub const COLOUR_STOPS: [[u8; 3]; 11] = [
    [5, 48, 97],
    [33, 102, 172],
    [67, 147, 195],
    [146, 197, 222],
    [209, 229, 240],
    [247, 247, 247],
    [253, 219, 199],
    [244, 165, 130],
    [214, 96, 77],
    [178, 24, 43],
    [103, 0, 31],
];

/// The colour of `u` on the map, sRGB: `u` in [−1, 1] (clamped; NaN gives the middle).
pub fn colour(u: f64) -> [u8; 3] {
    let u = if u.is_nan() { 0.0 } else { u.clamp(-1.0, 1.0) };
    let position = (u + 1.0) / 2.0 * (COLOUR_STOPS.len() - 1) as f64;
    let below = (position.floor() as usize).min(COLOUR_STOPS.len() - 2);
    let f = position - below as f64;
    let (c0, c1) = (COLOUR_STOPS[below], COLOUR_STOPS[below + 1]);
    std::array::from_fn(|k| (f64::from(c0[k]) + f * (f64::from(c1[k]) - f64::from(c0[k]))).round() as u8)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stops_are_hit_exactly_and_the_map_is_symmetric_in_strength() {
        for (k, stop) in COLOUR_STOPS.iter().enumerate() {
            assert_eq!(colour(-1.0 + 0.2 * k as f64), *stop, "stop {k}");
        }
        assert_eq!(colour(-7.0), COLOUR_STOPS[0]);
        assert_eq!(colour(f64::INFINITY), COLOUR_STOPS[10]);
        // Lightness falls alike on both sides: the sum of channels is within a few percent.
        let light = |c: [u8; 3]| c.iter().map(|&v| f64::from(v)).sum::<f64>();
        for u in [0.1, 0.3, 0.5, 0.7, 0.9] {
            let (minus, plus) = (light(colour(-u)), light(colour(u)));
            assert!((minus - plus).abs() / minus.max(plus) < 0.25, "u = {u}: {minus} vs {plus}");
        }
    }
}
