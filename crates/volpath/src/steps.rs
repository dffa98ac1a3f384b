//! The samplers of a walk's steps inside the medium, as the path loop
//! ([`crate::integrator::trace`]) asks for them: the classical walk's ([`SpectralWeight`]'s
//! flights, the phase function's directions) or the guided walks' ([`crate::guided`]), and what a
//! guided walk remembers along its path ([`Memory`]).

use glam::Vec3;

use crate::guided::{Dwivedi, Flight, WalkSampling};
use crate::spectral::SpectralWeight;

/// The walk's samplers inside the medium, as the path loop ([`crate::integrator::trace`]) uses
/// them: the classical ones ([`SpectralWeight`]'s flights, the phase function's directions), or
/// the guided technique's mixture with them (`Some`: [`Dwivedi`]). With the classical walk every
/// step is computed exactly as before guided walks existed (the same random numbers, the same
/// arithmetic).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Steps(pub Option<Dwivedi>);

/// What a walk remembers along its path: the outward normal where it last entered the medium
/// (guided walks), and the mixed density of the direction its last scattering drew, over the
/// channels and techniques as the path mixed them (guided walks and chromatic phase functions;
/// `None`: the direction came from the boundary or the camera, or has one density in every
/// channel).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Memory {
    pub normal: Vec3,
    pub drawn: Option<f32>,
}

impl Default for Memory {
    fn default() -> Self {
        Memory {
            normal: Vec3::Z,
            drawn: None,
        }
    }
}

impl Memory {
    /// The path meets the boundary at `hit` from inside or not (`inside`): a direction after it
    /// is the boundary's, and a path from outside that enters enters there (one that is
    /// reflected takes the normal of where it enters next).
    #[inline(always)]
    pub fn at_boundary(&mut self, inside: bool, hit: &geometry::Hit) {
        self.drawn = None;
        if !inside {
            self.normal = hit.ns;
        }
    }
}

impl Steps {
    /// The walk's samplers for `walks` in a medium of `albedo`, and the path's weight `w` with
    /// its sampler drawn (one uniform, with guided walks only).
    #[inline(always)]
    pub fn start(
        walks: WalkSampling,
        albedo: &[f32; 3],
        w: SpectralWeight,
        s: &mut crate::rng::Sampler,
    ) -> (Steps, SpectralWeight) {
        let steps = Steps(walks.guide(albedo));
        let w = match &steps.0 {
            Some(dw) => w.with_techniques(dw.probability, s.next_f32() < dw.probability),
            None => w,
        };
        (steps, w)
    }

    /// The flight along `d` of a walk that remembers `mem` (`None` with the classical walk).
    #[inline(always)]
    pub fn flight(&self, d: Vec3, mem: &Memory) -> Option<Flight> {
        self.0.as_ref().map(|dw| dw.flight(d.dot(mem.normal)))
    }

    /// A free-flight distance (one uniform).
    #[inline(always)]
    pub fn distance(
        &self,
        f: Option<&Flight>,
        sigma_t: &[f32; 3],
        w: &SpectralWeight,
        s: &mut crate::rng::Sampler,
    ) -> f32 {
        match (&self.0, f) {
            (Some(dw), Some(f)) => dw.sample_distance(f, sigma_t, w, s.next_f32()),
            _ => w.sample_distance(sigma_t, s.next_f32()),
        }
    }

    /// The flight passed a boundary at `t`.
    #[inline(always)]
    pub fn pass(&self, f: Option<&Flight>, w: &mut SpectralWeight, sigma_t: &[f32; 3], t: f32) {
        match (&self.0, f) {
            (Some(dw), Some(f)) => dw.pass(f, w, sigma_t, t),
            _ => w.pass(sigma_t, t),
        }
    }

    /// The flight scattered at `t`.
    #[inline(always)]
    pub fn scatter(
        &self,
        f: Option<&Flight>,
        w: &mut SpectralWeight,
        sigma_t: &[f32; 3],
        albedo: &[f32; 3],
        t: f32,
    ) {
        match (&self.0, f) {
            (Some(dw), Some(f)) => dw.scatter(f, w, sigma_t, albedo, t),
            _ => w.scatter(sigma_t, albedo, t),
        }
    }

    /// The density of the walk's own way from the last scattering to the boundary point at `t`
    /// along `d`: the direction's density (the phase function's `phase_density` with the
    /// classical walk, the mixture `mem` holds with guided walks) times the probability that the
    /// flight passes `t`, mixed as the path mixes its channels (and samplers).
    #[inline(always)]
    pub fn pass_density(
        &self,
        f: Option<&Flight>,
        mem: &Memory,
        w: &SpectralWeight,
        sigma_t: &[f32; 3],
        t: f32,
        phase_density: impl FnOnce() -> f32,
    ) -> f32 {
        let direction = mem.drawn.unwrap_or_else(phase_density);
        match (&self.0, f) {
            (Some(dw), Some(f)) => direction * dw.pass_probability(f, w, sigma_t, t),
            _ => direction * w.pass_probability(sigma_t, t),
        }
    }

    /// A new direction at a scattering vertex reached along `d` (two uniforms), from the hero
    /// channel's phase function (or the guide). With guided walks `mem` keeps its mixed density
    /// ([`Dwivedi::sample_direction`]). With a chromatic phase function the classical walk does
    /// too, and weighs the channels by their densities p_{g_j}(ω) as it does a flight
    /// ([`SpectralWeight::segment`]: f_j = p_j = p_{g_j}(ω)); with one g that weight is 1.
    #[inline(always)]
    pub fn direction(
        &self,
        phase: &crate::phase::ChannelHg,
        d: Vec3,
        mem: &mut Memory,
        w: &mut SpectralWeight,
        s: &mut crate::rng::Sampler,
    ) -> Vec3 {
        let (u1, u2) = (s.next_f32(), s.next_f32());
        let hero = w.hero;
        match &self.0 {
            Some(dw) => {
                let classical = |u1, u2| phase.sample(hero, d, u1, u2);
                let (dir, density) =
                    dw.sample_direction(mem.normal, w, [u1, u2], classical, |o| phase.eval(d, o));
                mem.drawn = Some(density);
                dir
            }
            None if phase.is_uniform() => phase.sample(hero, d, u1, u2),
            None => {
                let dir = phase.sample(hero, d, u1, u2);
                let fp = phase.eval(d, dir);
                mem.drawn = Some(w.mixture([fp, fp]));
                w.segment(fp, [fp, fp]);
                dir
            }
        }
    }
}
