//! One control period (1 ms), its order written once: the control task's cycle, then
//! the link service's pass (receive, jobs, transmit: `LinkService::pass`), then the
//! background worker.
//!
//! On the target the order comes from the tasks' priorities (`main.rs`): the control
//! task (priority 3, 1 kHz timer) runs `Controller::control_cycle` and then pends the
//! link service and the worker (priority 1, the link first); each calls the one
//! function for its part. The host bench (`sim::Bench`) and the cycle benchmark
//! (`bin/m2cyclebench.rs`) run the same parts in the same order through [`period`].

/// The three parts of a period, as a bench drives them.
pub trait Period {
    /// The control task: one control cycle.
    fn control(&mut self);
    /// The link service: one pass (`LinkService::pass`).
    fn link(&mut self);
    /// The background worker: its step(s) of the period.
    fn worker(&mut self);
}

/// One period, in the firmware's order.
pub fn period(p: &mut impl Period) {
    p.control();
    p.link();
    p.worker();
}
