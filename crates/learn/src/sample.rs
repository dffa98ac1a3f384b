//! One training sample (docs/model.md §5 step 5), the fixed-size record of the samples file.

use bssrdf::nn::N_POLY;

/// One exit sample of a random walk together with its configuration.
///
/// Light space (LS, docs/model.md §3.3) is the Duff frame of `e3 = −in_dir` at the entry point;
/// `poly_ls` are the fitted polynomial's coefficients rotated into it (scaled coordinates, units
/// of σ_n), `out_ls` is `R_LSᵀ(out_pos − in_pos)/σ_n`, the training target of the VAE (§6).
/// All medium parameters are the ORIGINAL (not reduced) ones; the network inputs are computed
/// from them by [`bssrdf::nn::Normalisation::normalise`] with the reduced albedo α'.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Sample {
    /// Light-space polynomial coefficients (c_0 = 0).
    pub poly_ls: [f32; N_POLY],
    /// Exit position relative to the entry point, in the LS frame, in units of σ_n.
    pub out_ls: [f32; 3],
    /// Single-scattering albedo α.
    pub albedo: f32,
    /// Extinction σ_t (1/world unit; the shapes are ~20 units across as in VKJ19).
    pub sigma_t: f32,
    /// Henyey–Greenstein g.
    pub g: f32,
    /// Relative index of refraction η.
    pub eta: f32,
    /// Probability that a walk of this configuration is absorbed (absorbed / attempts).
    pub absorption_prob: f32,
    /// σ_n of the medium (world units), docs/model.md §2.
    pub sigma_n: f32,
    /// Entry point (world).
    pub in_pos: [f32; 3],
    /// Incident direction into the medium after alignment (world, unit).
    pub in_dir: [f32; 3],
    /// Polynomial normal at the entry point (world, unit).
    pub in_normal: [f32; 3],
    /// Exit point (world), on the polynomial surface.
    pub out_pos: [f32; 3],
    /// Polynomial normal at the exit point (world, unit, outward).
    pub out_normal: [f32; 3],
    /// Exit direction (world, unit, leaving the medium).
    pub out_dir: [f32; 3],
    /// Number of scattering events of the walk.
    pub bounces: u32,
    /// Index of the configuration the sample belongs to.
    pub config: u32,
}

/// Size of one record in bytes.
pub const SAMPLE_BYTES: usize = std::mem::size_of::<Sample>();
