//! Frames to images and touches: the reconstructor, the image, touches and the noise test,
//! segmentation, the sensitivity of the chain, colours, and the values a board sends.

pub mod colour;
pub mod image;
pub mod inverse;
pub mod noise;
pub mod segmentation;
pub mod sensitivity;
pub mod touch;
pub mod values;
