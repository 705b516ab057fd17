//! Tests of the LPM CPU core (spec tests T1–T24 that apply to it).
