//! The events a frame's status calls for (the reference taken, the noise measured again,
//! channels dropped), each also said on stderr.

use eitskin::inverse::Hyperparameter;
use eitskin::pipeline::{Pipeline, Status};
use eitskin_io::stream::Event;

/// Says a [`channel_event`] on stderr, for whoever watches `run` (`serve` reports its sensors'
/// events itself, with their names).
pub fn say(event: &Event) {
    match event {
        Event::ReferenceTaken { detail, .. } | Event::NoiseUpdated { detail, .. } => eprintln!("eitskin run: {detail}"),
        Event::ChannelsDropped { seq, detail, .. } => eprintln!("warning: frame seq {seq}: {detail}"),
        _ => {}
    }
}

/// The event a frame's status calls for (said on stderr by [`say`]): the reference taken (with λ and
/// the channels left out, those of the spec's mask, from 0, named apart), or channels dropped;
/// `None` for any other frame.
pub fn channel_event(
    seq: u64,
    status: Status,
    pipeline: &Pipeline,
    hyperparameter: Hyperparameter,
    masked: &[usize],
) -> Option<Event> {
    let one_based = |channels: &[usize]| channels.iter().map(|m| m + 1).collect::<Vec<usize>>();
    match status {
        Status::Referencing { collected, needed } if collected == needed => {
            let lambda = pipeline.hyperparameter();
            let chosen = hyperparameter == Hyperparameter::Auto;
            let normalised = pipeline.chain().reconstructor().params().normalised;
            let dropped = one_based(&pipeline.dropped_channels());
            let how =
                if chosen { format!(" (chosen from the noise of {needed} reference frames)") } else { String::new() };
            let (by_spec, by_data): (Vec<usize>, Vec<usize>) = dropped.iter().partition(|m| masked.contains(&(*m - 1)));
            let mut left_out = String::new();
            if !by_spec.is_empty() {
                left_out += &format!("; channels {by_spec:?} left out (the spec drops them)");
            }
            if !by_data.is_empty() {
                left_out +=
                    &format!("; channels {by_data:?} left out (missing from a reference frame, or a zero reference)");
            }
            let (threshold, noise) = noise_figures(pipeline);
            let measured = pipeline.noise_measured();
            let test = match threshold {
                Some(z) => format!(
                    "; noise {:.3} % per value ({}), a touch needs z ≥ {z:.2}",
                    100.0 * noise,
                    if measured { "measured" } else { "assumed: one reference frame" }
                ),
                None => String::new(),
            };
            let detail = format!("reference taken; λ = {lambda:.4}{how}{left_out}{test}");
            Some(Event::ReferenceTaken {
                hyperparameter: lambda,
                chosen,
                normalised,
                channels_dropped: dropped,
                threshold,
                noise: Some(noise),
                noise_measured: measured,
                image_noise: pipeline.significance().map(|s| s.typical_std()),
                detail,
            })
        }
        Status::NoiseUpdated => {
            let (threshold, noise) = noise_figures(pipeline);
            let frames = pipeline.noise().map_or(0.0, |n| n.frames());
            let reference = pipeline.noise().map_or(0, |n| n.reference_frames());
            let lambda = pipeline.hyperparameter();
            let z = threshold.map_or(String::new(), |z| format!(", a touch needs z ≥ {z:.2}"));
            let detail = format!(
                "noise measured on {frames:.0} frames, reference the mean of {reference}: {:.3} % per value; λ = {lambda:.4}{z}",
                100.0 * noise
            );
            let image_noise = pipeline.significance().map(|s| s.typical_std());
            Some(Event::NoiseUpdated { seq, frames, hyperparameter: lambda, threshold, noise, image_noise, detail })
        }
        Status::ChannelsDropped { .. } => {
            let channels = one_based(pipeline.newly_dropped());
            let dropped = pipeline.dropped_channels().len();
            let detail = format!(
                "channel(s) {channels:?} went bad (not finite) and are dropped until the reference is \
                 re-taken ({dropped} dropped in all); imaging goes on without them"
            );
            Some(Event::ChannelsDropped { seq, channels, dropped, detail })
        }
        _ => None,
    }
}

/// The threshold z of the pipeline's noise test (if any) and the median channel's relative noise.
fn noise_figures(pipeline: &Pipeline) -> (Option<f64>, f64) {
    let threshold = pipeline.significance().map(|s| s.threshold());
    let mut relative: Vec<f64> = pipeline.noise().map_or(Vec::new(), |n| n.relative_variance());
    relative.retain(|v| v.is_finite());
    relative.sort_by(f64::total_cmp);
    (threshold, relative.get(relative.len() / 2).map_or(0.0, |v| v.sqrt()))
}
