//! Multi-view inverse rendering of homogeneous translucent media with the learned BSSRDF
//! (Son et al. 2024 §5) or, as the volumetric baseline, the volumetric path tracer: the forward
//! models behind one interface ([`forward`]), parameters and their parameterisation ([`params`]), the Adam loop with
//! checkpoints ([`optimize`]), its reports ([`report`]), the uncertainty of an estimate from the
//! images ([`uncertainty`]), the checks of a run's health ([`health`]), its re-render by the volumetric path tracer
//! ([`consistency`]), the tracer's own sensitivity along the σ_t valley ([`sensitivity`]) and the parametric-bootstrap bias correction of a recovered medium
//! ([`bootstrap`]), the learned estimators' derivative images against differences
//! ([`gradcheck`]), the seconds per iteration of every model × estimator ([`timing`]), a whole
//! recovery from a dataset folder behind one typed configuration ([`recovery`]: what `optimize`
//! runs), and the render loops over a list of views and into a dataset ([`views`]). The
//! gradient estimators themselves
//! (`ours`, `ours-alpha-offsets`, `naive`, `fd`) live in [`bssrdf::diff`].

pub mod bootstrap;
pub mod consistency;
mod error;
pub mod forward;
pub mod gradcheck;
pub mod health;
pub mod observer;
pub mod optimize;
pub mod params;
pub mod sensitivity;
pub mod timing;
pub mod uncertainty;
pub mod views;
