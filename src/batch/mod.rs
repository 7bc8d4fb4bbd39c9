//! Many jobs from one manifest (`objnerf batch`): a JSON Lines file, one job a line (a scene and
//! its stages: sfm, extract, remove, export), run one after the other here, or one task a job
//! on Ray (`scripts/ray_batch.py`) or one Slurm array index a job (`docs/batch.md`), all
//! through [`run_job`], so every engine writes the same folders:
//!
//! ```text
//! OUT/<id>/                 the job's stages' outputs (sfm/, extract/, remove/, export/) and
//!                           job.json (its figures); built under a temporary name, renamed
//!                           into place when every stage succeeded: present means complete
//! OUT/logs/<id>.log         the stages' command lines and output (the last attempt)
//! OUT/records/<id>.json     the job's record: status, time, peak memory, scores, warnings, error
//! OUT/summary.json          every record, in the manifest's order
//! ```

pub mod manifest;
pub mod record;
pub mod run;

pub use manifest::{Job, Manifest, Resources, StageCommand};
pub use record::{BatchSummary, JobRecord, Status};
pub use run::{die_with_parent, run_batch, run_job, summarize};
