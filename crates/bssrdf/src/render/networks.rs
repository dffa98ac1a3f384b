//! Stage 2 of a row of the learned renderer: the feature MLP, the absorption S_abs and the
//! decoder, batched over the row's samples ([`run_networks`]; with the walk entry sampler the
//! decoder's outputs are replaced by walk exits), and the same networks on any batch of inputs
//! with their latents ([`evaluate_networks`], also used for the estimators' offset samples).

use super::{EntrySampler, LearnedScene, RenderError, RowBuffers, walk_entries, walk_media};
use crate::nn::{INPUT_DIM, LATENT_DIM, POSITION_DIM, ShapeAdaptiveModel, Workspace};

/// The outputs of the three networks for a batch of samples.
#[derive(Default)]
pub(crate) struct NetOutputs {
    pub(crate) feats: Vec<f32>,
    /// Absorb (S_abs = 1 − Absorb).
    pub(crate) absorb: Vec<f32>,
    /// Decoder outputs (light-space offsets in units of σ_n).
    pub(crate) y: Vec<[f32; POSITION_DIM]>,
}

/// Stage 2 of a row: feature MLP, S_abs and the decoder, batched over the row's samples.
/// With [`EntrySampler::Walks`] the decoder's outputs are replaced by walk exits.
pub(crate) fn run_networks(scene: &LearnedScene, buf: &mut RowBuffers) -> Result<(), RenderError> {
    evaluate_networks(
        scene.model,
        &buf.inputs,
        &buf.z,
        &mut buf.point,
        &mut buf.net,
        &mut buf.ws,
    )?;
    if scene.settings.entry == EntrySampler::Walks {
        let k = |c: usize| scene.descriptor_scale[c];
        let media = walk_media(scene);
        walk_entries(
            &media,
            &buf.pending,
            &buf.coeffs,
            &buf.dcoeffs,
            k,
            &mut buf.net.y,
        );
    }
    Ok(())
}

/// Feature MLP, Absorb and decoder for the samples `inputs` with latents `z` (one per input).
pub(crate) fn evaluate_networks(
    model: &ShapeAdaptiveModel,
    inputs: &[[f32; INPUT_DIM]],
    z: &[[f32; LATENT_DIM]],
    point: &mut Vec<u32>,
    out: &mut NetOutputs,
    ws: &mut Workspace,
) -> Result<(), RenderError> {
    let n = inputs.len();
    if n == 0 {
        return Ok(());
    }
    out.feats.resize(n * model.feature_dim(), 0.0);
    out.absorb.resize(n, 0.0);
    out.y.resize(n, [0.0; POSITION_DIM]);
    point.clear();
    point.extend(0..n as u32);
    model.features_with(inputs, &mut out.feats, ws)?;
    model.absorb_with(&out.feats, &mut out.absorb, ws)?;
    model.decode_with(&out.feats, z, point, &mut out.y, ws)?;
    Ok(())
}
