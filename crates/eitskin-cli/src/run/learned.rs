//! `run --model`: a learned model's answer for each frame with a touch, from its Δv against the
//! pipeline's reference, allocation-free after the first frame.

use eitskin::learn::{LearnedModel, PredictScratch};
use eitskin::pipeline::Pipeline;
use eitskin_io::stream::Learned;

/// A learned model and the buffers of its answers.
pub struct LearnedAnswers {
    model: LearnedModel,
    difference: Vec<f64>,
    scratch: PredictScratch,
}

impl LearnedAnswers {
    /// Answers of `model`.
    pub fn new(model: LearnedModel) -> LearnedAnswers {
        let channels = model.channels();
        LearnedAnswers { model, difference: Vec::with_capacity(channels), scratch: PredictScratch::default() }
    }

    /// The model's answer for `frame` (protocol order), positions in units of `metres` m, when
    /// the pipeline found a touch in it and has a reference, and the model answers (press
    /// features give none for a Δv like no press).
    pub fn answer(&mut self, frame: &[f64], pipeline: &Pipeline, metres: f64) -> Option<Learned> {
        let reference = pipeline.reference()?;
        if pipeline.touches().is_empty() || frame.len() != self.model.channels() {
            return None;
        }
        self.difference.clear();
        self.difference.extend(frame.iter().zip(reference).map(|(v, r)| v - r));
        self.model.predict(&self.difference, &mut self.scratch).map(|answer| Learned::new(&answer, metres))
    }
}
