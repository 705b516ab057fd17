//! Binary of [`experiments::i3rc_step_cloud`].
experiments::experiment_main!(experiments::i3rc_step_cloud::I3rcStepCloud);
