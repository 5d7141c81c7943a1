//! The memory estimate of a model (models/memory.rs) against the bytes it really takes, and the
//! refusal of a grid that does not fit.

use granrs_core::grid::{BoundaryConditions, Field, Grid, Location, Side, VelocityBc};
use granrs_core::models::{available_memory, ActiveRegion, ConvectionScheme, Material, ModelConfig, TwoPhaseModel, WindowSides};
use granrs_core::pore_pressure::{PoreFormulation, PorePressureConfig, PoreTimeScheme};
use granrs_core::rheology::{RheologyConfig, RheologyLaw, SigmaLocation};
use granrs_core::time_stepping::ViscousScheme;
use granrs_core::walls::side::SideWalls;
use granrs_core::Error;
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicI64, Ordering};

/// Bytes held through the global allocator (all threads of this test binary).
static LIVE: AtomicI64 = AtomicI64::new(0);

struct Counting;

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        LIVE.fetch_add(l.size() as i64, Ordering::SeqCst);
        unsafe { System.alloc(l) }
    }
    unsafe fn alloc_zeroed(&self, l: Layout) -> *mut u8 {
        LIVE.fetch_add(l.size() as i64, Ordering::SeqCst);
        unsafe { System.alloc_zeroed(l) }
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        LIVE.fetch_sub(l.size() as i64, Ordering::SeqCst);
        unsafe { System.dealloc(p, l) }
    }
    unsafe fn realloc(&self, p: *mut u8, l: Layout, new: usize) -> *mut u8 {
        LIVE.fetch_add(new as i64 - l.size() as i64, Ordering::SeqCst);
        unsafe { System.realloc(p, l, new) }
    }
}

#[global_allocator]
static ALLOC: Counting = Counting;

/// The column collapse's set-up on `nx × ny` cells (two phases, open top, a Coulomb base).
fn column(nx: usize, ny: usize) -> ModelConfig {
    let grid = Grid::new(nx, ny, 2.0 * nx as f64 / ny as f64 * 0.25, 0.5).unwrap();
    let bc = BoundaryConditions::uniform(VelocityBc::FreeSlip).with(Side::Bottom, VelocityBc::Coulomb).with(Side::Top, VelocityBc::Outflow);
    let mut cfg = ModelConfig::single_phase(grid, bc, Material { density: 1450.0, viscosity: 0.1 });
    cfg.light = Some(Material { density: 1.2, viscosity: 2e-5 });
    cfg.gravity = [0.0, -9.81];
    cfg.rheology = RheologyConfig::new(RheologyLaw::DruckerPrager { friction_angle: 27.0 });
    cfg.rheology.wall_friction_angle = Some(27.0);
    cfg.rheology.picard_max_iterations = 50;
    cfg.time.fixed_dt = Some(1e-4);
    cfg
}

/// Live bytes after building `cfg`'s model and taking two steps (the snapshot of the state is
/// made by the first), and the estimate.
fn measure(cfg: ModelConfig) -> (i64, i64) {
    let estimate = cfg.memory_estimate() as i64;
    let before = LIVE.load(Ordering::SeqCst);
    let mut m = TwoPhaseModel::new(cfg.clone()).unwrap();
    let g = cfg.grid.clone();
    m.phi.assign(&Field::from_fn(&g, Location::Centre, |x, y| (0.3 - x).min(0.25 - y)));
    m.fields_changed();
    for _ in 0..2 {
        m.step().unwrap();
    }
    let held = LIVE.load(Ordering::SeqCst) - before;
    drop(m);
    (estimate, held)
}

#[test]
fn the_estimate_matches_the_bytes_a_model_takes() {
    let n = 128;
    let mut cases: Vec<(&str, ModelConfig)> = Vec::new();
    let dry = column(4 * n, n / 2);
    cases.push(("column, dry", dry.clone()));
    let mut wet = dry.clone();
    wet.pore =
        Some(PorePressureConfig { diffusivity: 0.05, formulation: PoreFormulation::GranularOnly, basal_flux: None, time_scheme: PoreTimeScheme::Implicit });
    cases.push(("column, fluidised", wet.clone()));
    let mut walls = wet.clone();
    walls.rheology.side_walls = Some(SideWalls { width: 0.1, friction_angle: 27.0 });
    walls.rheology.sigma_location = SigmaLocation::Centres;
    cases.push(("fluidised, side walls, Σ at centres", walls));
    let mut anderson = dry.clone();
    anderson.rheology.anderson_depth = 3;
    cases.push(("dry, Anderson mixing of depth 3", anderson));
    let mut pieces = dry.clone();
    pieces.redistance.piece_removal_cells = 4;
    cases.push(("dry, detached pieces removed", pieces));
    let mut film = dry.clone();
    film.redistance.mass_correction_film = 1.0;
    cases.push(("dry, the film-sparing mass correction", film));
    let mut clsvof = dry.clone();
    clsvof.interface_transport = granrs_core::levelset::InterfaceTransport::Clsvof;
    clsvof.mass_correction = false;
    cases.push(("dry, the volume fraction and its moments (clsvof)", clsvof));
    let mut restarts = dry.clone();
    restarts.rheology.proximal_restarts = 5;
    restarts.rheology.picard_tol = 1e-3;
    restarts.redistance_every = 1;
    cases.push(("dry, proximal restarts, redistancing every step", restarts));
    let mut mu_i = wet.clone();
    mu_i.rheology = RheologyConfig::new(RheologyLaw::MuI { mu_s: 0.51, mu_2: 0.9, i0: 0.28, grain_diameter: 75e-6, grain_density: 2500.0 });
    mu_i.rheology.wall_friction_angle = Some(27.0);
    mu_i.rheology.picard_max_iterations = 50;
    mu_i.rheology.picard_tol = 1e-3;
    cases.push(("fluidised, mu(I)", mu_i));
    let mut weno = dry.clone();
    weno.convection_scheme = ConvectionScheme::Weno5;
    weno.viscous = ViscousScheme::Explicit;
    cases.push(("dry, WENO5 convection, explicit viscous term", weno));
    let mut extended = dry.clone();
    extended.redistance.extended_velocity = true;
    cases.push(("dry, extended transport velocity", extended));
    let mut granular = dry.clone();
    granular.free_surface = true;
    cases.push(("granular-only", granular));
    let mut newtonian = dry.clone();
    newtonian.rheology = RheologyConfig::default();
    newtonian.bc = BoundaryConditions::uniform(VelocityBc::NoSlip).with(Side::Top, VelocityBc::Outflow);
    cases.push(("Newtonian", newtonian));
    for (name, cfg) in cases {
        let (estimate, held) = measure(cfg);
        let ratio = estimate as f64 / held as f64;
        println!("{name}: estimate {estimate} B, held {held} B, ratio {ratio:.4}");
        // what the estimate leaves out is O(nx + ny) (wall vectors, block partial sums, the
        // pool's bookkeeping): measured 0.24–0.31 % of the bytes held on 512 × 64 cells, for
        // every case here; 0.5 % leaves room for the other tests of this binary allocating
        // meanwhile (the count is process-wide)
        assert!((ratio - 1.0).abs() < 0.005, "{name}: estimate {estimate} B against {held} B held (ratio {ratio})");
    }
}

#[test]
fn the_estimate_of_an_active_region_counts_the_window() {
    let mut cfg = column(256, 32);
    let whole = cfg.memory_estimate();
    cfg.active_region = Some(ActiveRegion { band: 4, align: 8, sides: WindowSides::Walls });
    assert_eq!(cfg.memory_estimate(), 2 * whole);
}

#[test]
fn a_grid_that_does_not_fit_is_refused_before_it_is_allocated() {
    let Some(avail) = available_memory() else {
        // no /proc/meminfo: no check is made (models/memory.rs)
        return;
    };
    let grid = Grid::new(65536, 65536, 65536.0, 65536.0).unwrap();
    let cfg = ModelConfig::single_phase(grid, BoundaryConditions::uniform(VelocityBc::NoSlip), Material { density: 1.0, viscosity: 1.0 });
    let need = cfg.memory_estimate();
    // ≈ 70 arrays of 2^32 values: about 2.4 TB
    assert!(need > 2_000_000_000_000, "{need}");
    assert!(need > avail, "this machine has {avail} B available");
    let before = LIVE.load(Ordering::SeqCst);
    match TwoPhaseModel::new(cfg) {
        Err(Error::InvalidParameter { name, value, allowed }) => {
            assert_eq!(name, "grid");
            assert_eq!(value, "65536 x 65536 cells");
            assert!(allowed.contains("its estimate is") && allowed.contains("GiB available"), "{allowed}");
        }
        Err(e) => panic!("expected the refusal, got {e}"),
        Ok(_) => panic!("a 65536 x 65536 model was built"),
    }
    // nothing of the model's size was allocated (other tests of this binary may hold a few MB)
    assert!(LIVE.load(Ordering::SeqCst) - before < 1 << 30);
}
