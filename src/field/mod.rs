//! The object field: a voxel-grid radiance field of one object (DVGO-style density,
//! Plenoxels-style spherical-harmonic colour), trained on CPU from masked views.
//!
//! Pipeline: [`view`] turns a scene's images and masks into training views (and cameras into
//! [`RayCamera`]s), [`bounds`] finds the object's box (the masks' visual hull) and the voxel
//! size, [`rays`] keeps the rays that meet the box, [`depth`] adds optional depth targets,
//! [`edge`] marks the band along a segmented mask's edge, [`session`] sizes the grid and runs
//! [`train`], which fits the [`model::Field`] with sparse per-voxel Adam; [`render`] marches
//! rays through it (forward and hand-written backward), [`eval`] renders and scores views,
//! [`checks`] are the self-checks of a trained field, [`holdout`] splits views and measures
//! depth error, [`io`] saves and loads the model file, and [`fit`] is training on a scene as
//! one call.
//!
//! Measurements (SH degree, batch and step sweeps, headline runs on lego, the Pareto sweep, the
//! demo objects' depth error, learning rates) are in `examples/results/field.md` beside the
//! benchmark JSON; test PSNR against training time on lego at 200^2, 400^2 and 800^2, sparse
//! against dense, with peak RSS, in `examples/results/field_sizes.{json,svg}`.
//!
//! # Design, and why
//! - **One vertex grid; in each brick the densities apart from the colour** (per 4^3 brick its
//!   64 raw densities, then each vertex's `[SH r, SH g, SH b]` or features together): every
//!   sample reads its density, few read their colour, so a cell's 8 densities lie in two cache
//!   lines and a vertex's colour is one run for the gather and the scatter. With the next
//!   sample's cell prefetched and alpha from one exp, lego 800^2's finest stage takes 8.5% more
//!   steps a second on the large model (13 channels), ~2% on the usual one (9), where the
//!   scatter and Adam now touching two places a vertex cost most of what the march gains
//!   (examples/results/field.md, "A cheaper sample").
//! - **Colour by view count: a feature grid + small network ([`colour_net`]) for an object
//!   seen from at least 80 views, SH degree 1 on the grid below that (and for scene fields)**
//!   (`SetupConfig::net_min_views`). The network (8 features per vertex, 32 hidden units, the
//!   view direction as its SH basis to degree 3, colour only where a sample's weight reaches
//!   3e-3 at a voxel's step, DVGO's fast_color_thres, scaled with the step) fits lego better with
//!   less memory (+0.5 dB at 400^2 in 300 s, +0.6 at 800^2 in 20 min; equal at 200^2), but its
//!   view dependence does not hold between few views: 0.9 dB below SH 1 on the demo's sphere
//!   (30 views) and 0.24 below on fox (42). Degree 1 beats degree 0 (less view-dependent colour)
//!   and degree 2 (28 floats per vertex: slower steps, a coarser grid in the memory budget)
//!   (`examples/results/field.md`, "Colour" and "Colour by view count"). On views of 100 000
//!   pixels or more a second hidden layer of 32 follows the first (`SetupConfig::net_hidden2`):
//!   its ~4x the network's work a sample hides behind a large grid's memory traffic (lego 800^2
//!   in 20 min: four runs with one layer 34.42-34.52 dB, four with two 34.51-34.65; 400^2 in
//!   300 s 34.11 -> 34.31) but not on small views (200^2 in 60 s 33.37 -> 32.99, so they keep
//!   one layer; "A second hidden layer by default").
//! - **A larger model for a longer run** (`SetupConfig::large_model_passes`): where the run's
//!   steps or time budget afford ~15 passes over the training pixels, a network field takes 12
//!   features and 64 hidden units on a grid 1.3x finer: lego 200^2 in 300 s 33.65 -> 34.05 dB;
//!   shorter runs keep the usual model, which fits sooner (`examples/results/field.md`, "A
//!   larger model for a longer run").
//! - **A shallower decay for a network field, ending on the mean of its last parameters**
//!   (`TrainConfig::lr_final_network`, 0.3 of the starting rates at the end, against 0.03 for
//!   SH fields; Polyak averaging, `TrainConfig::average_from_network`: the grid's values and the
//!   network's weights every 500 steps over the last 20% of the run, as SWA does): sparse Adam
//!   moves a vertex only when a ray crosses it, at lego 800^2 about once in 200 steps, so a
//!   steep decay leaves the late touches too small to finish the detail, and a shallow one
//!   leaves each vertex scattering by about the rate around where its gradients balance, which
//!   the mean takes out. Alone, 0.1 was best ("Learning rates that decay less"); the mean
//!   gained 0.06 dB over the same run's last values at 0.1 ("The mean of the last
//!   parameters"), 0.27 at 0.3, which lifts lego 800^2 in 20 min from 34.51-34.65 dB (six runs)
//!   to 34.69-34.71 (two) and 200^2 in 60 s from 33.29-33.37 to 33.46 (examples/results/field.md,
//!   "The mean with a shallower decay"). The mean holds one more copy of the grid's values for
//!   the last fifth of the run.
//! - **Density post-activated** as DVGO: interpolate the raw value, then softplus and alpha, so a
//!   cell can hold a sharp surface; `delta` is in finest-voxel units so coarse-to-fine growth keeps
//!   densities meaningful.
//! - **Box and occupancy from the masks' visual hull** (voting: a point survives if at most 20%
//!   of the views that see it show background there, so occlusions in visible-part masks do not
//!   cut the object), carved at the first stage's cells; every 100 steps the cells whose densest
//!   corner is under 1% opaque a step are pruned (post-activation is monotone, so no point in
//!   them is denser): that faint shell in front of the surfaces held 80% of a step's samples and
//!   taught nothing (lego 200^2 in 60 s: 31.0 -> 32.3 dB; examples/results/field.md, "Pruning
//!   the faint shell"). Empty bricks, and empty blocks of 4^3 bricks, are jumped over, asked of
//!   a bitset small enough to stay in cache ([`live`]; lego 800^2: steps 8% faster, renders 21%).
//! - **Segmented masks are trusted to within 2 px** ([`edge`]): SAM stops two rows short of the
//!   demo mug's base in every view, and a field fitted to that mask as exact alpha has no base.
//!   Band pixels whose colour argues against their mask (nearer the sure object's colours than
//!   the sure background's, or the reverse) take the photo, rendered over the background
//!   inpainted behind the object, as their colour target; the mask's alpha stays only as the weak
//!   alpha term. Forward demo, the mug held out, over the scene without it: 24.3 -> 26.1 dB
//!   inside its true mask, 27.6 -> 27.5 in the 4 px around it (no fringe). Letting every band
//!   pixel's colour decide grew a floor-coloured fringe (22.3 dB around). Off for exact masks
//!   (an image's alpha, the demo's truth).
//! - **Sparse bricks** ([`grid`]): only the 4^3-vertex bricks around occupied cells are stored,
//!   so memory follows the occupied shell (lego 400^2 at the dense grid's resolution: 647 vs
//!   910 MiB peak). The finest stage's resolution is one voxel per pixel footprint, coarsened
//!   until its bricks fit the memory budget; the dense first stage, at half that resolution,
//!   may take only a quarter of the budget (`SetupConfig::first_stage_share`). When it could
//!   take all of it, large images left the finest stage no room: lego 400^2 in 300 s 29.7 dB,
//!   now 31.8; 800^2 in 20 min 30.8, now 31.9; the ring's scene field 27.2 -> 29.6 dB in 150 s;
//!   each with less memory (examples/results/field.md, "The first stage's share"). Where the
//!   budget coarsens the first stage, an object seen from 80 views or more starts at 0.35 of
//!   the finest resolution, with a middle stage, so the finest is not held to twice the
//!   first's (`TrainConfig::stages_when_capped`, `SetupConfig::fine_min_views`): lego 800^2 in
//!   20 min 32.96 -> 33.72 dB in the same 1 GiB; fox's 42 views keep the two stages (the finer
//!   grid overfits them: "A coarser start where the budget binds").
//! - **Deterministic multi-threading**: fixed 256-ray chunks with per-ray seeded randomness write
//!   gradient records bucketed by z-slab; each slab sums its records in chunk order. No atomics,
//!   no per-thread dense gradient copies, and the same grid for a seed at any thread count.
//! - **Single rays per batch, not runs of neighbouring pixels** (`TrainConfig::ray_run`, an
//!   option): runs share grid corners, so gathers and the gradient scatter hit cache and steps
//!   get 25-58% cheaper on large grids, but their rays teach less a step: no better PSNR on lego
//!   at a fixed time, 0.2-0.4 dB less on fox and the mug's removal at a fixed step count
//!   (examples/results/field.md).
//! - **Sparse Adam** on the vertices a batch touched (sorted, so the pass sweeps memory forward),
//!   its moments in bfloat16 (the pass is bound by memory: 12 bytes a channel instead of 16, the
//!   same PSNR, 13% cheaper fine-stage steps on lego 800^2); TV on those vertices only. TV is
//!   off by default: with our sum-scaled loss even 1e-6 cost 11 dB at 100^2 in 40 s (it
//!   overpowers the per-ray data gradient); keep it <= 1e-8 if used.
//! - **Depth loss on the normalised depth** (sum w t / sum w) in finest-voxel units: the
//!   unnormalised sum reads a 0.5% opacity deficit at 2 m as a 1 cm error, and in metres a 1 cm
//!   error squared is too small to matter next to the colour loss.
//! - **Free space in front of the sparse points** (object fields, `--depth sparse`): the weight a ray puts more than 3
//!   voxels nearer than its target is penalised, since a camera sees the point through empty
//!   space. Colour alone leaves faint matter there; with it the demo objects' held-out PSNR moved
//!   -0.02 to +1.25 dB and training took 0.55-0.75 of the time (fewer samples a ray).
//! - **One ray through each pixel's centre** when a view is rendered or scored, though every
//!   truth here integrates over its pixels: 2 x 2 rays (`RenderOptions::pixel_samples`,
//!   `--pixel-samples` on `render` and `eval`) score the same lego 800^2 models +0.10 dB, but
//!   the demo objects' closely fit fields 0.35-0.61 dB less and lego 200^2 0.02-0.14 less
//!   (examples/results/field.md, "Pixels as the mean of 2 x 2 rays").

pub mod activation;
pub mod bounds;
pub mod colour_net;
pub mod eval;
pub mod grid;
pub mod holdout;
pub mod io;
pub mod live;
pub mod march;
pub mod model;
mod occupancy;
pub mod rays;
pub mod session;
pub mod sh;
pub mod train;
pub mod view;

pub use march::RenderOptions;
pub use model::{Field, FieldConfig};
pub use session::{prepare, run, SetupConfig, StopRule};
pub use train::{TrainConfig, Trainer};
pub use view::{load_views, MaskSource, RayCamera, View};
