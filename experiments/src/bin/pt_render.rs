//! Binary of [`experiments::pt_render`].
experiments::experiment_main!(experiments::pt_render::PtRender);
