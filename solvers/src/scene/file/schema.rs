//! The file schema: the serde view of a format-1 document, kept apart from the data model
//! ([`super::super::Scene`]) that [`super::convert`] and [`super::medium`] build from it.

use serde::{Deserialize, Serialize};

#[derive(Deserialize)]
pub(super) struct FormatProbe {
    pub(super) format: Option<toml::Value>,
}

#[derive(Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub(super) struct Doc {
    pub(super) format: i64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) description: Option<String>,
    pub(super) medium: MediumDoc,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) phase: Option<PhaseDoc>,
    #[serde(default, rename = "light", skip_serializing_if = "Vec::is_empty")]
    pub(super) lights: Vec<LightDoc>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) camera: Option<CameraDoc>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) sampler: Option<SamplerDoc>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) outputs: Option<OutputsDoc>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) effects: Option<EffectsDoc>,
}

#[derive(Debug, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub(super) struct EffectsDoc {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) only: Option<Vec<String>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) exclude: Option<Vec<String>>,
}

#[derive(Debug, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub(super) struct MediumDoc {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) generator: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) params: Option<toml::Table>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) file: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) density_scale: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) albedo: Option<toml::Value>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) emission: Option<toml::Value>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) min: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) max: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) sigma_t_rgb: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) albedo_rgb: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) emission_rgb: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) vdb: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) grid: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) interpolation: Option<String>,
}

#[derive(Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub(super) struct PhaseDoc {
    #[serde(rename = "type")]
    pub(super) kind: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) g: Option<f64>,
}

#[derive(Debug, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub(super) struct LightDoc {
    #[serde(rename = "type")]
    pub(super) kind: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) position: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) power: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) direction: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) irradiance: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) center: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) radius: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) radiance: Option<f64>,
}

#[derive(Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub(super) struct CameraDoc {
    pub(super) eye: [f64; 3],
    pub(super) target: [f64; 3],
    pub(super) up: [f64; 3],
    pub(super) projection: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) width: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) fov_y: Option<f64>,
    pub(super) resolution: [usize; 2],
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) hide_background: Option<bool>,
}

#[derive(Debug, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub(super) struct SamplerDoc {
    pub(super) spp: u32,
    pub(super) seed: u64,
}

/// The `[sampler]` defaults, also used when the table is absent: `spp = 16`, `seed = 0`.
impl Default for SamplerDoc {
    fn default() -> Self {
        Self { spp: 16, seed: 0 }
    }
}

#[derive(Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub(super) struct OutputsDoc {
    #[serde(default)]
    pub(super) write: Vec<String>,
}
