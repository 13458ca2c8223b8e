//! `GET /v1/jobs/{id}/scene`: what the live page's 3D view draws of a `rigid_bodies` job, once:
//! each body's name, whether it is fixed, whether it is a half-space (a square facing its free
//! side, which the view leaves out when the camera is behind it: the walls of a box would
//! otherwise hide what is inside), and its surface in its body frame
//! ([`signorini_collision::surface`]); the poses come per step with the job's stream (the
//! `state` events of `/v1/jobs/{id}/events?state=true`). Another job is refused naming
//! `model.scene`.

use super::AppState;
use crate::error::ApiError;
use axum::Json;
use axum::extract::{Path, State};
use serde_json::{Value, json};
use signorini_collision::surface::scene_surfaces;
use signorini_core::rigid::Shape;
use signorini_core::spec::{ModelSpec, SpecError};

/// The bodies of a rigid job with their surfaces.
pub(super) async fn job_scene(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<Json<Value>, ApiError> {
    crate::engine::check_id(&id)?;
    let spec = state.engine.stored_spec(&id)?;
    let Some(ModelSpec::RigidBodies(rigid)) = &spec.model else {
        return Err(ApiError::Invalid(SpecError::new(
            "model.scene",
            "only a rigid_bodies job has a 3D scene",
        )));
    };
    let scene = rigid.validate().map_err(ApiError::Invalid)?;
    let surfaces = scene_surfaces(&scene)
        .map_err(|e| ApiError::Invalid(SpecError::new("model.bodies", e.to_string())))?;
    let bodies: Vec<Value> = scene
        .names
        .iter()
        .zip(&scene.bodies)
        .zip(&surfaces)
        .map(|((name, body), s)| {
            json!({
                "name": name,
                "fixed": body.fixed,
                "half_space": matches!(body.shape, Shape::HalfSpace { .. }),
                "points": s.points,
                "faces": s.faces
            })
        })
        .collect();
    Ok(Json(json!({ "id": id, "bodies": bodies })))
}
