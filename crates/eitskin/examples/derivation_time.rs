use eitskin::chain::Chain;
use eitskin::noise::{NoiseModel, Significance};
use eitskin::pipeline::{Deferred, Pipeline, PipelineParams};
use eitskin::sim::VirtualSensor;
use eitskin::{Reconstructor, ReconstructorParams, SensorSpec, TouchParams};
use std::time::Instant;

fn main() {
    let spec = SensorSpec::square_hydrogel();
    let model = spec.forward_model().unwrap();
    let recon = Reconstructor::new(&model, 1.0, &ReconstructorParams::default()).unwrap();
    println!(
        "pixels {} meas {} tri {}",
        recon.blank_image().values.len(),
        recon.measurements(),
        model.mesh().triangles().len()
    );
    let chain = Chain::new(recon.clone(), TouchParams::default());
    let params = PipelineParams { auto_hyperparameter: true, ..PipelineParams::default() };
    let mut p = Pipeline::new(chain, params);
    p.defer_derivations(Deferred::All);
    let mut skin = VirtualSensor::new(&spec, 3).unwrap();
    let mut jobs = Vec::new();
    for _ in 0..400 {
        p.process(&skin.frame().unwrap()).unwrap();
        if let Some(job) = p.take_derivation() {
            let t = Instant::now();
            let d = job.clone().run();
            jobs.push((job.is_reference(), t.elapsed().as_secs_f64() * 1e3));
            p.deliver(d);
        }
    }
    println!("jobs {:?}", jobs);
    let lin = recon.linearisation();
    let ch = recon.channels().clone();
    for _ in 0..6 {
        let t = Instant::now();
        let (r2, l) = recon.with_auto_hyperparameter(ch.clone(), None).unwrap();
        let ta = t.elapsed().as_secs_f64() * 1e3;
        let t = Instant::now();
        let _r3 = recon.derive(l, r2.channels().clone()).unwrap();
        let td = t.elapsed().as_secs_f64() * 1e3;
        let v = p.reference().unwrap().to_vec();
        let noise = NoiseModel::assumed(1e-4, v.len(), 10);
        let t = Instant::now();
        let _s = Significance::new(&r2, &v, &noise, 1, eitskin::image::Polarity::Decrease, 1e-3).unwrap();
        let ts = t.elapsed().as_secs_f64() * 1e3;
        println!("auto {ta:.1} ms (derive {td:.1}), significance {ts:.1} ms; lin {}", lin.jacobian().nrows());
    }
}
