//! The shape-adaptive model: the four networks with their normalisation, and the batched
//! inference entry points (features, Absorb and its input derivative, decoder, encoder).

use rayon::prelude::*;

use super::{
    CHUNK_ROWS, Dense, INPUT_DIM, LATENT_DIM, Mlp, Normalisation, POSITION_DIM, Workspace,
    batch_rows, bias_act, chunks, expect_len, grow, matmul_wt, par_rows, run_layers, sigmoid,
    with_scratch,
};
use crate::model::{ModelError, ModelInfo};

/// The VAE encoder (training only): hidden ReLU layers on `[x(3) ⊕ f]`, then two linear heads.
#[derive(Clone, Debug, PartialEq)]
pub struct Encoder {
    hidden: Mlp,
    mean: Dense,
    logvar: Dense,
}

impl Encoder {
    /// An encoder from its hidden layers (ReLU on all) and its two heads (μ, log σ²).
    pub fn new(hidden: Vec<Dense>, mean: Dense, logvar: Dense) -> Result<Self, ModelError> {
        let hidden = Mlp::new(hidden, true)?;
        for (name, head) in [("mean", &mean), ("logvar", &logvar)] {
            if head.n_in != hidden.n_out() || head.n_out != LATENT_DIM {
                return Err(ModelError::Architecture(format!(
                    "encoder {name} head is {} -> {}, expected {} -> {LATENT_DIM}",
                    head.n_in,
                    head.n_out,
                    hidden.n_out()
                )));
            }
        }
        Ok(Self {
            hidden,
            mean,
            logvar,
        })
    }

    /// Hidden layers (ReLU on all).
    pub fn hidden(&self) -> &Mlp {
        &self.hidden
    }

    /// Mean head.
    pub fn mean(&self) -> &Dense {
        &self.mean
    }

    /// Log-variance head.
    pub fn logvar(&self) -> &Dense {
        &self.logvar
    }

    /// Mutable parts (hidden, mean head, log-variance head).
    pub fn parts_mut(&mut self) -> (&mut Mlp, &mut Dense, &mut Dense) {
        (&mut self.hidden, &mut self.mean, &mut self.logvar)
    }

    /// Number of parameters.
    pub fn n_params(&self) -> usize {
        self.hidden.n_params() + self.mean.n_params() + self.logvar.n_params()
    }
}

/// The learned shape-adaptive BSSRDF: networks, input normalisation and model information.
///
/// Invariants (checked by [`ShapeAdaptiveModel::new`]): the feature MLP maps 23 inputs to F
/// features with ReLU on every layer; the absorption MLP maps F to 1; the decoder maps 4 + F
/// to 3; the encoder, if any, maps 3 + F to two heads of 4.
#[derive(Clone, Debug, PartialEq)]
pub struct ShapeAdaptiveModel {
    feature: Mlp,
    absorption: Mlp,
    decoder: Mlp,
    encoder: Option<Encoder>,
    normalisation: Normalisation,
    info: ModelInfo,
}

impl ShapeAdaptiveModel {
    /// Assembles a model from its layers and checks that the blocks fit together.
    pub fn new(
        feature: Vec<Dense>,
        absorption: Vec<Dense>,
        decoder: Vec<Dense>,
        encoder: Option<Encoder>,
        normalisation: Normalisation,
        info: ModelInfo,
    ) -> Result<Self, ModelError> {
        let arch = |block: &str, e: ModelError| match e {
            ModelError::Architecture(m) => ModelError::Architecture(format!("{block}: {m}")),
            e => e,
        };
        let feature = Mlp::new(feature, true).map_err(|e| arch("feature MLP", e))?;
        let absorption = Mlp::new(absorption, false).map_err(|e| arch("absorption MLP", e))?;
        let decoder = Mlp::new(decoder, false).map_err(|e| arch("decoder", e))?;
        let f = feature.n_out();
        let mut problems = Vec::new();
        if feature.n_in() != INPUT_DIM {
            problems.push(format!(
                "feature MLP takes {} inputs, expected {INPUT_DIM}",
                feature.n_in()
            ));
        }
        if absorption.n_in() != f || absorption.n_out() != 1 {
            problems.push(format!(
                "absorption MLP is {} -> {}, expected {f} -> 1 (F = {f} features)",
                absorption.n_in(),
                absorption.n_out()
            ));
        }
        if decoder.n_in() != LATENT_DIM + f || decoder.n_out() != POSITION_DIM {
            problems.push(format!(
                "decoder is {} -> {}, expected {} -> {POSITION_DIM} (z(4) + F = {f} features)",
                decoder.n_in(),
                decoder.n_out(),
                LATENT_DIM + f
            ));
        }
        if let Some(e) = &encoder
            && e.hidden.n_in() != POSITION_DIM + f
        {
            problems.push(format!(
                "encoder takes {} inputs, expected {} (x(3) + F = {f} features)",
                e.hidden.n_in(),
                POSITION_DIM + f
            ));
        }
        if let Some((name, i, v)) = normalisation.first_non_finite() {
            problems.push(format!("normalisation {name}[{i}] is {v}"));
        }
        if !problems.is_empty() {
            return Err(ModelError::Architecture(problems.join("; ")));
        }
        Ok(Self {
            feature,
            absorption,
            decoder,
            encoder,
            normalisation,
            info,
        })
    }

    /// Feature MLP (ReLU on every layer).
    pub fn feature_mlp(&self) -> &Mlp {
        &self.feature
    }

    /// Absorption MLP (before the sigmoid).
    pub fn absorption_mlp(&self) -> &Mlp {
        &self.absorption
    }

    /// Decoder.
    pub fn decoder(&self) -> &Mlp {
        &self.decoder
    }

    /// Encoder (present in trained models; absent in render-only ones).
    pub fn encoder(&self) -> Option<&Encoder> {
        self.encoder.as_ref()
    }

    /// Mutable networks, for training: (feature, absorption, decoder, encoder).
    pub fn networks_mut(&mut self) -> (&mut Mlp, &mut Mlp, &mut Mlp, Option<&mut Encoder>) {
        (
            &mut self.feature,
            &mut self.absorption,
            &mut self.decoder,
            self.encoder.as_mut(),
        )
    }

    /// Input normalisation.
    pub fn normalisation(&self) -> &Normalisation {
        &self.normalisation
    }

    /// Conventions and provenance.
    pub fn info(&self) -> &ModelInfo {
        &self.info
    }

    /// Mutable conventions and provenance.
    pub fn info_mut(&mut self) -> &mut ModelInfo {
        &mut self.info
    }

    /// Feature width F.
    pub fn feature_dim(&self) -> usize {
        self.feature.n_out()
    }

    /// Number of parameters used at render time (feature + absorption + decoder).
    pub fn render_params(&self) -> usize {
        self.feature.n_params() + self.absorption.n_params() + self.decoder.n_params()
    }

    // -- features --------------------------------------------------------------------------

    /// Feature vectors (F per row of `out`) of a batch of normalised inputs, on this thread.
    pub fn features_with(
        &self,
        inputs: &[[f32; INPUT_DIM]],
        out: &mut [f32],
        ws: &mut Workspace,
    ) -> Result<(), ModelError> {
        self.feature.forward_with(inputs.as_flattened(), out, ws)
    }

    /// Feature vectors of a batch of normalised inputs, rows split over the rayon pool.
    pub fn features(&self, inputs: &[[f32; INPUT_DIM]], out: &mut [f32]) -> Result<(), ModelError> {
        self.feature.forward(inputs.as_flattened(), out)
    }

    // -- absorption ------------------------------------------------------------------------

    /// Absorb = sigmoid(absorption MLP(f)) ∈ (0, 1) for a batch of feature vectors (F per row),
    /// on this thread.
    pub fn absorb_with(
        &self,
        features: &[f32],
        out: &mut [f32],
        ws: &mut Workspace,
    ) -> Result<(), ModelError> {
        self.absorption.forward_with(features, out, ws)?;
        out.iter_mut().for_each(|v| *v = sigmoid(*v));
        Ok(())
    }

    /// Absorb for a batch of feature vectors, rows split over the rayon pool.
    pub fn absorb(&self, features: &[f32], out: &mut [f32]) -> Result<(), ModelError> {
        self.absorption.forward(features, out)?;
        out.iter_mut().for_each(|v| *v = sigmoid(*v));
        Ok(())
    }

    /// Absorb and its derivative ∂Absorb/∂input_k with respect to the normalised input `k`
    /// (α_eff is [`ALBEDO_INPUT`]) for a batch of inputs, on this thread.
    ///
    /// Forward-mode: a tangent is pushed through the feature and absorption MLPs, masked by the
    /// ReLU derivative (taken as 0 at a pre-activation of exactly 0), then multiplied by
    /// σ'(a) = Absorb·(1 − Absorb). About twice the cost of the forward pass.
    pub fn absorb_input_derivative_with(
        &self,
        inputs: &[[f32; INPUT_DIM]],
        k: usize,
        absorb: &mut [f32],
        derivative: &mut [f32],
        ws: &mut Workspace,
    ) -> Result<(), ModelError> {
        self.check_derivative_args(inputs.len(), k, absorb.len(), derivative.len())?;
        let x = inputs.as_flattened();
        for r in chunks(inputs.len(), ws.chunk_rows) {
            self.absorb_tangent_chunk(
                &x[r.start * INPUT_DIM..r.end * INPUT_DIM],
                k,
                &mut absorb[r.clone()],
                &mut derivative[r],
                ws,
            );
        }
        Ok(())
    }

    /// Absorb and ∂Absorb/∂input_k, rows split over the rayon pool.
    pub fn absorb_input_derivative(
        &self,
        inputs: &[[f32; INPUT_DIM]],
        k: usize,
        absorb: &mut [f32],
        derivative: &mut [f32],
    ) -> Result<(), ModelError> {
        self.check_derivative_args(inputs.len(), k, absorb.len(), derivative.len())?;
        let x = inputs.as_flattened();
        absorb
            .par_chunks_mut(CHUNK_ROWS)
            .zip(derivative.par_chunks_mut(CHUNK_ROWS))
            .enumerate()
            .for_each(|(i, (a, d))| {
                let s = i * CHUNK_ROWS;
                let xs = &x[s * INPUT_DIM..(s + a.len()) * INPUT_DIM];
                with_scratch(|ws| {
                    for r in chunks(a.len(), ws.chunk_rows) {
                        self.absorb_tangent_chunk(
                            &xs[r.start * INPUT_DIM..r.end * INPUT_DIM],
                            k,
                            &mut a[r.clone()],
                            &mut d[r],
                            ws,
                        );
                    }
                });
            });
        Ok(())
    }

    fn check_derivative_args(
        &self,
        n: usize,
        k: usize,
        n_absorb: usize,
        n_deriv: usize,
    ) -> Result<(), ModelError> {
        if k >= INPUT_DIM {
            return Err(ModelError::Batch(format!(
                "input index {k} is out of range (the model has {INPUT_DIM} inputs)"
            )));
        }
        expect_len("absorb output", n_absorb, n)?;
        expect_len("derivative output", n_deriv, n)
    }

    fn absorb_tangent_chunk(
        &self,
        x: &[f32],
        k: usize,
        absorb: &mut [f32],
        derivative: &mut [f32],
        ws: &mut Workspace,
    ) {
        let rows = absorb.len();
        let n_feature = self.feature.layers.len();
        let n_total = n_feature + self.absorption.layers.len();
        let layers = self
            .feature
            .layers
            .iter()
            .chain(self.absorption.layers.iter());
        let [va, vb] = &mut ws.bufs;
        let [ta, tb] = &mut ws.tangents;
        let (mut v_src, mut v_dst) = (va, vb);
        let (mut t_src, mut t_dst) = (ta, tb);
        for (i, layer) in layers.enumerate() {
            let relu = i + 1 < n_total;
            let (n_in, n_out) = (layer.n_in, layer.n_out);
            grow(v_dst, rows * n_out);
            grow(t_dst, rows * n_out);
            let v_in: &[f32] = if i == 0 { x } else { &v_src[..rows * n_in] };
            let v_out = &mut v_dst[..rows * n_out];
            let t_out = &mut t_dst[..rows * n_out];
            matmul_wt(v_in, rows, n_in, &layer.w, n_in, n_out, v_out);
            if i == 0 {
                // Tangent of the input is the unit vector e_k: W e_k is column k of W.
                for t_row in t_out.chunks_exact_mut(n_out) {
                    for (j, t) in t_row.iter_mut().enumerate() {
                        *t = layer.w[j * n_in + k];
                    }
                }
            } else {
                matmul_wt(
                    &t_src[..rows * n_in],
                    rows,
                    n_in,
                    &layer.w,
                    n_in,
                    n_out,
                    t_out,
                );
            }
            for (v_row, t_row) in v_out
                .chunks_exact_mut(n_out)
                .zip(t_out.chunks_exact_mut(n_out))
            {
                for j in 0..n_out {
                    let v = v_row[j] + layer.b[j];
                    if relu && v <= 0.0 {
                        v_row[j] = 0.0;
                        t_row[j] = 0.0;
                    } else {
                        v_row[j] = v;
                    }
                }
            }
            std::mem::swap(&mut v_src, &mut v_dst);
            std::mem::swap(&mut t_src, &mut t_dst);
        }
        // The last layer has one output: the absorption logit and its tangent.
        for r in 0..rows {
            let a = sigmoid(v_src[r]);
            absorb[r] = a;
            derivative[r] = a * (1.0 - a) * t_src[r];
        }
    }

    // -- decoder ---------------------------------------------------------------------------

    /// Decodes latent samples: `out[s] = decoder([z[s] ⊕ f_{point[s]}])` where `features` holds
    /// one feature vector (F values) per shading point and `point[s]` is the shading point of
    /// sample `s`. On this thread. Outputs are light-space offsets in units of σ_n.
    pub fn decode_with(
        &self,
        features: &[f32],
        z: &[[f32; LATENT_DIM]],
        point: &[u32],
        out: &mut [[f32; POSITION_DIM]],
        ws: &mut Workspace,
    ) -> Result<(), ModelError> {
        let n_points = self.check_decode_args(features, z.len(), point, out.len())?;
        let h = self.decoder.layers[0].n_out;
        let mut points = std::mem::take(&mut ws.points);
        grow(&mut points, n_points * h);
        self.decoder_point_part(features, n_points, &mut points[..n_points * h]);
        let out = out.as_flattened_mut();
        for r in chunks(z.len(), ws.chunk_rows) {
            self.decode_chunk(
                &points,
                &z[r.clone()],
                &point[r.clone()],
                &mut out[r.start * POSITION_DIM..r.end * POSITION_DIM],
                ws,
            );
        }
        ws.points = points;
        Ok(())
    }

    /// Decodes latent samples, split over the rayon pool. Allocates one buffer of
    /// `n_points × width of the first decoder layer` per call.
    pub fn decode(
        &self,
        features: &[f32],
        z: &[[f32; LATENT_DIM]],
        point: &[u32],
        out: &mut [[f32; POSITION_DIM]],
    ) -> Result<(), ModelError> {
        let n_points = self.check_decode_args(features, z.len(), point, out.len())?;
        let h = self.decoder.layers[0].n_out;
        let f = self.feature_dim();
        let mut points = vec![0.0f32; n_points * h];
        par_rows(&mut points, h, |r, p, _| {
            self.decoder_point_part(&features[r.start * f..r.end * f], r.len(), p);
        });
        par_rows(out.as_flattened_mut(), POSITION_DIM, |r, o, ws| {
            for c in chunks(r.len(), ws.chunk_rows) {
                let (s, e) = (r.start + c.start, r.start + c.end);
                self.decode_chunk(
                    &points,
                    &z[s..e],
                    &point[s..e],
                    &mut o[c.start * POSITION_DIM..c.end * POSITION_DIM],
                    ws,
                );
            }
        });
        Ok(())
    }

    fn check_decode_args(
        &self,
        features: &[f32],
        n_z: usize,
        point: &[u32],
        n_out: usize,
    ) -> Result<usize, ModelError> {
        let n_points = batch_rows("decoder features", features.len(), self.feature_dim())?;
        expect_len("sample-to-point index", point.len(), n_z)?;
        expect_len("decoder output", n_out, n_z)?;
        if let Some(s) = point.iter().position(|&p| p as usize >= n_points) {
            return Err(ModelError::Batch(format!(
                "sample {s} refers to shading point {} but only {n_points} feature vectors were given",
                point[s]
            )));
        }
        Ok(n_points)
    }

    /// Per-point part of the first decoder layer: `W_f f + b` (no activation).
    fn decoder_point_part(&self, features: &[f32], n_points: usize, out: &mut [f32]) {
        let l0 = &self.decoder.layers[0];
        let f = self.feature_dim();
        matmul_wt(
            features,
            n_points,
            f,
            &l0.w[LATENT_DIM..],
            l0.n_in,
            l0.n_out,
            out,
        );
        bias_act(out, &l0.b, false);
    }

    fn decode_chunk(
        &self,
        points: &[f32],
        z: &[[f32; LATENT_DIM]],
        point: &[u32],
        out: &mut [f32],
        ws: &mut Workspace,
    ) {
        let rows = z.len();
        let layers = &self.decoder.layers;
        let l0 = &layers[0];
        let h = l0.n_out;
        let single = layers.len() == 1;
        let hidden = &mut ws.hidden;
        grow(hidden, rows * h);
        let hidden = &mut hidden[..rows * h];
        // Per-sample part W_z z, then add the shared per-point part and apply the ReLU.
        matmul_wt(
            z.as_flattened(),
            rows,
            LATENT_DIM,
            &l0.w,
            l0.n_in,
            h,
            hidden,
        );
        for (row, &p) in hidden.chunks_exact_mut(h).zip(point) {
            let pre = &points[p as usize * h..(p as usize + 1) * h];
            if single {
                row.iter_mut().zip(pre).for_each(|(v, &q)| *v += q);
            } else {
                row.iter_mut()
                    .zip(pre)
                    .for_each(|(v, &q)| *v = (*v + q).max(0.0));
            }
        }
        if single {
            out.copy_from_slice(hidden);
        } else {
            run_layers(&layers[1..], false, hidden, rows, out, &mut ws.bufs);
        }
    }

    // -- encoder ---------------------------------------------------------------------------

    /// Encodes exit positions (training): `(μ, log σ²)[s] = encoder([x[s] ⊕ f_{point[s]}])`.
    /// On this thread. Errors if the model has no encoder.
    pub fn encode_with(
        &self,
        features: &[f32],
        x: &[[f32; POSITION_DIM]],
        point: &[u32],
        mean: &mut [[f32; LATENT_DIM]],
        logvar: &mut [[f32; LATENT_DIM]],
        ws: &mut Workspace,
    ) -> Result<(), ModelError> {
        let Some(enc) = &self.encoder else {
            return Err(ModelError::Batch(
                "this model has no encoder (render-only model)".to_string(),
            ));
        };
        let f = self.feature_dim();
        let n_points = batch_rows("encoder features", features.len(), f)?;
        expect_len("sample-to-point index", point.len(), x.len())?;
        expect_len("encoder mean output", mean.len(), x.len())?;
        expect_len("encoder log-variance output", logvar.len(), x.len())?;
        if let Some(s) = point.iter().position(|&p| p as usize >= n_points) {
            return Err(ModelError::Batch(format!(
                "sample {s} refers to shading point {} but only {n_points} feature vectors were given",
                point[s]
            )));
        }
        let n_in = POSITION_DIM + f;
        let width = enc.hidden.n_out();
        let (mean, logvar) = (mean.as_flattened_mut(), logvar.as_flattened_mut());
        for r in chunks(x.len(), ws.chunk_rows) {
            let rows = r.len();
            let mut concat = std::mem::take(&mut ws.points);
            grow(&mut concat, rows * n_in);
            for (row, (xs, &p)) in concat
                .chunks_exact_mut(n_in)
                .zip(x[r.clone()].iter().zip(&point[r.clone()]))
            {
                row[..POSITION_DIM].copy_from_slice(xs);
                row[POSITION_DIM..]
                    .copy_from_slice(&features[p as usize * f..(p as usize + 1) * f]);
            }
            grow(&mut ws.hidden, rows * width);
            run_layers(
                &enc.hidden.layers,
                true,
                &concat[..rows * n_in],
                rows,
                &mut ws.hidden[..rows * width],
                &mut ws.bufs,
            );
            let hid = &ws.hidden[..rows * width];
            let span = r.start * LATENT_DIM..r.end * LATENT_DIM;
            enc.mean
                .forward_rows(hid, rows, &mut mean[span.clone()], false);
            enc.logvar.forward_rows(hid, rows, &mut logvar[span], false);
            ws.points = concat;
        }
        Ok(())
    }
}
