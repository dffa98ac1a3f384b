//! The volumetric path tracer: a homogeneous medium inside one closed mesh, lit by a point light
//! (next-event estimation) and/or a constant environment.
//!
//! | parameter | meaning |
//! |---|---|
//! | σ_t, α (RGB) | extinction [1/unit], single-scattering albedo; σ_s = α σ_t |
//! | g (RGB) | Henyey–Greenstein anisotropy, one per channel or one for all |
//! | η | boundary: 1 = index-matched `null` interface (the paper's data); > 1 = dielectric |
//! | roughness | the dielectric's GGX α; 0 = smooth, > 0 = rough ([`crate::rough`]) |
//! | max_depth | Mitsuba 3 `volpath` semantics: depth counts real scatterings; NEE at scattering vertex k only if k < max_depth |
//! | rr_depth | Russian roulette once depth > rr_depth, survival q = min(max_k β_k, 1) |
//!
//! Radiance along a camera ray is estimated by free-flight sampling (hero channel with spectral
//! MIS, [`crate::spectral`]), phase-function sampling (the hero channel's g; a chromatic medium's
//! other channels enter the same MIS by their phase functions' densities), and NEE at every scattering vertex with
//! an unbiased estimate of the transmittance exp(−σ_t · ℓ) of the total length ℓ of the shadow
//! segment inside the mesh (re-entries included; [`crate::shadow`]). Boundary crossings do not
//! count as depth, except at a rough boundary, where each interaction does (Mitsuba 3's `volpath`
//! with `roughdielectric`).
//!
//! With η > 1 the camera side is exact (Fresnel reflection/refraction chosen with probability F,
//! total internal reflection, radiance scaled by 1/η_rel² across the interface). A point light
//! behind a smooth dielectric cannot be reached by a shadow ray (Mitsuba 3's `volpath` renders
//! such scenes black); we connect through the refraction by manifold NEE ([`crate::manifold`]),
//! which is exact for convex objects (see its limitations). A rough boundary is crossed by
//! sampling its BSDF and reaches the point light by next-event estimation at its own vertices,
//! as Mitsuba 3 does, combined with a connection from the scattering vertices near it guided by
//! the smooth refraction ([`crate::rough`]). Environment light works for every boundary.
//!
//! Queries. Free flights ask [`Accel::closest`] (which skips the BVH when the clearance grid rules
//! out a hit); the shadow rays read the light's lists ([`geometry::LightBins`]); a camera ray and
//! the path's queries along its line until the first scattering (index-matched boundary) read the
//! camera's per-pixel lists ([`CameraLine`]). Every list answers exactly as the BVH would.
//!
//! Limitations: the camera must be outside the object; the mesh must be closed.

use geometry::{Accel, FilmCursor, Hit, PixelBins};
use glam::Vec3;

use crate::phase::ChannelHg;
use crate::rng::Sampler;
use crate::rough;
use crate::steps::{Memory, Steps};
use crate::vertex::{Estimates, score};

pub use crate::settings::{
    ChannelSampling, DEFAULT_MAX_DEPTH, SpawnOffset, VolpathScene, VolpathSettings,
};
pub use crate::tally::{PathScore, Tally};

/// Upper bound on interface events per path (guards against numerical ping-pong).
const MAX_INTERFACE_EVENTS: u32 = 1024;

/// Estimate the radiance arriving at `origin` along `-dir` (one sample, RGB).
pub fn radiance(
    scene: &VolpathScene,
    settings: &VolpathSettings,
    origin: Vec3,
    dir: Vec3,
    s: &mut Sampler,
) -> [f32; 3] {
    radiance_primary(scene, settings, origin, dir, None, s)
}

/// A camera ray that came through the camera's per-pixel triangle lists ([`PixelBins`]): they
/// answer its first hit and every later closest-hit query along the same line (the first free
/// flight inside an index-matched medium, the search for a re-entry behind it), bit for bit as
/// the BVH would ([`PixelBins::closest_first`], [`PixelBins::closest_next`]).
pub struct CameraLine<'a> {
    bins: &'a PixelBins,
    cursor: FilmCursor<'a>,
    project: &'a dyn Fn(Vec3) -> Option<(f32, f32, f32)>,
}

impl<'a> CameraLine<'a> {
    /// The ray through the film point `(fx, fy)` (pixels) of the view that `bins` were built
    /// for with the projector `project` (`(px, py, depth)` of a world point); the ray's
    /// direction must be generated from that film point.
    #[inline]
    pub fn new(
        bins: &'a PixelBins,
        fx: f32,
        fy: f32,
        project: &'a dyn Fn(Vec3) -> Option<(f32, f32, f32)>,
    ) -> Self {
        CameraLine {
            bins,
            cursor: bins.cursor(fx, fy),
            project,
        }
    }

    /// `accel.closest(o, d, 0, tmax)`: from the lists of `line` where it is given and they can
    /// answer it, else from the BVH.
    #[inline]
    fn closest_on(
        line: Option<&mut Self>,
        accel: &Accel,
        o: Vec3,
        d: Vec3,
        tmax: f32,
    ) -> Option<Hit> {
        line.and_then(|l| l.closest(accel, o, d, tmax))
            .unwrap_or_else(|| accel.closest(o, d, 0.0, tmax))
    }

    /// The camera ray's first hit along `d` (`accel.closest(camera, d, 0, ∞)`), from the lists.
    #[inline]
    fn first(&mut self, accel: &Accel, d: Vec3) -> Option<Hit> {
        (self.bins).closest_first(accel, &mut self.cursor, d, 0.0, f32::INFINITY)
    }

    /// `accel.closest(o, d, 0, tmax)` from the lists, or `None` when they cannot answer it.
    #[inline]
    fn closest(&mut self, accel: &Accel, o: Vec3, d: Vec3, tmax: f32) -> Option<Option<Hit>> {
        let at = (self.project)(o)?;
        let c = &mut self.cursor;
        self.bins.closest_next(accel, c, o, at, d, 0.0, tmax)
    }
}

/// [`radiance`] for a camera ray: with `line`, its closest-hit queries along the camera ray's
/// line go through the camera's lists ([`CameraLine`]); `None` asks the BVH for everything.
/// The result is the same either way.
pub fn radiance_primary(
    scene: &VolpathScene,
    settings: &VolpathSettings,
    origin: Vec3,
    dir: Vec3,
    line: Option<CameraLine>,
    s: &mut Sampler,
) -> [f32; 3] {
    trace::<[f32; 3]>(scene, settings, origin, dir, line, s)
}

/// [`radiance_primary`] for any [`Tally`]: the path loop of the tracer.
pub fn trace<T: Tally>(
    scene: &VolpathScene,
    settings: &VolpathSettings,
    origin: Vec3,
    dir: Vec3,
    line: Option<CameraLine>,
    s: &mut Sampler,
) -> T {
    let m = &scene.medium;
    let phase = ChannelHg::new(m.g.channels());
    let w = settings.channel_sampling.start(s.next_below(3) as usize);
    let (steps, mut w) = Steps::start(settings.walks, &m.albedo, w, s);
    let mut mem = Memory::default();
    let mut l = T::default();
    // The path's length inside the medium so far (its free flights), and per channel
    // Σ ∂ ln p/∂g over the phase-function directions sampled so far (with T::SCORES_PHASE).
    let (mut len, mut phase_score) = (0.0f32, [0.0f32; 3]);
    let (mut o, mut d, mut inside) = (origin, dir, false);
    // Real scatterings (what the path's throughput depends on the medium by) and the depth
    // (the scatterings, and the rough boundary's interactions, as Mitsuba 3's `volpath`
    // counts them).
    let (mut k, mut depth, mut interface_events) = (0u32, 0u32, 0u32);
    let rough = (m.eta != 1.0 && m.roughness > 0.0)
        .then(|| base::microfacet::RoughDielectric::new(m.eta, m.roughness));
    // The last scattering's guided connection through a rough boundary, until the path meets
    // the boundary, and then the weight of that meeting's next-event estimate against it.
    let (mut guide, mut flight_weight): (Option<rough::Guide>, f32) = (None, 1.0);
    // The path left the medium through a triangle whose plane has the whole mesh behind it
    // (`Accel::exit_is_final`) and moves away from that plane: it cannot meet the mesh again,
    // so the query for a re-entry is skipped (the BVH would answer "no hit").
    let mut escaped = false;
    // The path still runs along the camera ray (an index-matched boundary does not turn it; no
    // scattering yet), so the camera's lists can answer its queries.
    let mut line = line;
    let mut on_line = m.eta == 1.0;
    let est = Estimates {
        scene,
        settings,
        phase: &phase,
        rough: rough.as_ref(),
        dwivedi: steps.0.as_ref(),
    };
    // The closest hit along `o + t·d`, `t < tmax`.
    let closest = |line: &mut Option<CameraLine>, on_line: bool, o: Vec3, d: Vec3, tmax: f32| {
        CameraLine::closest_on(line.as_mut().filter(|_| on_line), scene.accel, o, d, tmax)
    };

    loop {
        // The boundary the path meets next, or a scattering event / the end of the path.
        let hit = if inside {
            let flight = steps.flight(d, &mem);
            let t = steps.distance(flight.as_ref(), &m.sigma_t, &w, s);
            if let Some(hit) = closest(&mut line, on_line, o, d, t) {
                if let Some(g) = guide.take() {
                    // A uniform phase function's density (a chromatic one's direction keeps its
                    // mixed density in `mem`).
                    let phase_density = || phase.channel(0).eval(g.d_in(), d);
                    let f = flight.as_ref();
                    let pa = steps.pass_density(f, &mem, &w, &m.sigma_t, hit.t, phase_density);
                    flight_weight = g.flight_weight(pa, d);
                }
                steps.pass(flight.as_ref(), &mut w, &m.sigma_t, hit.t);
                len += hit.t;
                hit
            } else {
                // Real scattering event.
                o += t * d;
                on_line = false;
                steps.scatter(flight.as_ref(), &mut w, &m.sigma_t, &m.albedo, t);
                len += t;
                k += 1;
                depth += 1;
                if depth >= settings.max_depth {
                    break;
                }
                let sc = score::<T>(&phase, k, len, phase_score, None);
                if !est.at_scattering(o, d, mem.normal, sc, depth, &mut w, &mut guide, &mut l, s) {
                    break;
                }
                let d_new = steps.direction(&phase, d, &mut mem, &mut w, s);
                if T::SCORES_PHASE {
                    let ds = phase.d_log_dg(d.dot(d_new));
                    for c in 0..3 {
                        phase_score[c] += ds[c];
                    }
                }
                d = d_new;
                continue;
            }
        } else {
            let hit = match &mut line {
                _ if escaped => None,
                Some(l) if interface_events == 0 => l.first(scene.accel, d),
                _ => closest(&mut line, on_line, o, d, f32::INFINITY),
            };
            let Some(hit) = hit else {
                est.escape(score::<T>(&phase, k, len, phase_score, None), &w, &mut l);
                break;
            };
            hit
        };
        interface_events += 1;
        if interface_events > MAX_INTERFACE_EVENTS {
            break;
        }
        let sc = score::<T>(&phase, k, len, phase_score, None);
        mem.at_boundary(inside, &hit);
        let ray = (&mut o, &mut d, &mut inside);
        if !est.at_boundary(
            &hit,
            sc,
            &mut depth,
            &mut flight_weight,
            ray,
            &mut w,
            &mut l,
            s,
        ) {
            break;
        }
        escaped = !inside && d.dot(hit.ng) > 0.0 && scene.accel.exit_is_final(hit.tri);
    }
    l.finish();
    l
}
