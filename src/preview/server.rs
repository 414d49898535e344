//! The HTTP side: the page's own assets (embedded in the binary), the
//! opened character's scene and frames, nothing else.
//!
//! | route | answer |
//! |---|---|
//! | `GET /`, `/app.js`, `/style.css` | the page |
//! | `GET /api/scene` | [`SceneInfo`](super::protocol::SceneInfo) as JSON |
//! | `GET /api/strokes` | per-point widths and colours (binary) |
//! | `POST /api/frame` | a [`FrameRequest`] → one frame (binary) |
//! | `GET /api/ws` | websocket: `FrameRequest` text messages → binary frames |
//! | `POST /api/render` | a [`RenderRequest`] → PNG |
//!
//! Requests whose `Host` is not this server's loopback address get 403
//! (a web page elsewhere cannot reach the server by DNS rebinding), and so
//! do requests whose `Origin` is not this server's own page (browsers
//! send it on a websocket handshake and a POST: a page elsewhere could
//! otherwise open `ws://127.0.0.1:PORT/api/ws` and read frames); bad JSON
//! or values get 400, frames that cannot be evaluated 422.

use std::future::Future;
use std::sync::Arc;

use axum::body::Bytes;
use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::extract::{FromRequest, Request, State};
use axum::http::{header, HeaderMap, HeaderValue, StatusCode};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use axum::{Json, Router};

use super::connections::BODY_TIMEOUT;
use super::evaluator::{Evaluator, JobError};
use super::protocol::{from_json, BadRequest, FrameRequest, RenderRequest};

const INDEX: &str = include_str!("page/index.html");
const APP: &str = include_str!("page/app.js");
const STYLE: &str = include_str!("page/style.css");

/// Largest websocket message accepted (a frame request is a few hundred bytes).
const MAX_WS_MESSAGE: usize = 64 * 1024;

/// Shared by every handler.
pub struct AppState {
    pub evaluator: Evaluator,
    /// Accepted `Host` header values (`None`: any, when not on loopback).
    pub hosts: Option<Vec<String>>,
}

/// An error answer: a status and a JSON `{"error": message}` body.
pub struct ApiError(StatusCode, String);

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let body = Json(serde_json::json!({ "error": self.1 }));
        (self.0, no_store(), body).into_response()
    }
}

impl From<BadRequest> for ApiError {
    fn from(b: BadRequest) -> Self {
        ApiError(StatusCode::BAD_REQUEST, b.0)
    }
}

impl From<JobError> for ApiError {
    fn from(e: JobError) -> Self {
        match e {
            JobError::Unprocessable(m) => ApiError(StatusCode::UNPROCESSABLE_ENTITY, m),
            JobError::Internal(m) => ApiError(StatusCode::INTERNAL_SERVER_ERROR, m),
        }
    }
}

fn no_store() -> [(header::HeaderName, HeaderValue); 1] {
    [(header::CACHE_CONTROL, HeaderValue::from_static("no-store"))]
}

/// The router over an opened character.
pub fn router(state: Arc<AppState>) -> Router {
    Router::new()
        .route("/", get(|| async { page(INDEX, "text/html; charset=utf-8") }))
        .route("/index.html", get(|| async { page(INDEX, "text/html; charset=utf-8") }))
        .route("/app.js", get(|| async { page(APP, "text/javascript; charset=utf-8") }))
        .route("/style.css", get(|| async { page(STYLE, "text/css; charset=utf-8") }))
        .route("/api/scene", get(scene))
        .route("/api/strokes", get(strokes))
        .route("/api/frame", post(frame))
        .route("/api/render", post(render))
        .route("/api/ws", get(ws))
        .fallback(|| async { ApiError(StatusCode::NOT_FOUND, "no such page".into()) })
        .layer(middleware::map_response(json_errors))
        .layer(middleware::from_fn_with_state(state.clone(), check_host))
        .with_state(state)
}

/// Errors axum answers itself (a method an address does not take, a body
/// over its 2 MB limit) come as plain text or empty: every error of this
/// API is JSON `{"error": ...}`, so they are rewritten as such.
async fn json_errors(resp: Response) -> Response {
    let status = resp.status();
    let is_json = resp
        .headers()
        .get(header::CONTENT_TYPE)
        .is_some_and(|v| v.as_bytes().starts_with(b"application/json"));
    if !(status.is_client_error() || status.is_server_error()) || is_json {
        return resp;
    }
    let message = match status {
        StatusCode::METHOD_NOT_ALLOWED => {
            "this address does not take that method (GET /api/scene, GET /api/strokes, POST /api/frame, POST /api/render)".to_string()
        }
        StatusCode::PAYLOAD_TOO_LARGE => "the request body is over the 2 MB limit".to_string(),
        other => other.canonical_reason().unwrap_or("request failed").to_string(),
    };
    ApiError(status, message).into_response()
}

fn page(body: &'static str, content_type: &'static str) -> Response {
    (
        [
            (header::CONTENT_TYPE, HeaderValue::from_static(content_type)),
            (
                header::CONTENT_SECURITY_POLICY,
                HeaderValue::from_static(
                    "default-src 'self'; img-src 'self' blob: data:; connect-src 'self'; object-src 'none'; base-uri 'none'",
                ),
            ),
            (header::X_CONTENT_TYPE_OPTIONS, HeaderValue::from_static("nosniff")),
        ],
        body,
    )
        .into_response()
}

async fn check_host(State(state): State<Arc<AppState>>, req: Request, next: Next) -> Response {
    let host = req
        .headers()
        .get(header::HOST)
        .and_then(|h| h.to_str().ok())
        .unwrap_or("");
    let ok = match &state.hosts {
        None => true,
        Some(hosts) => hosts.iter().any(|h| h.eq_ignore_ascii_case(host)),
    };
    if !ok {
        return ApiError(
            StatusCode::FORBIDDEN,
            format!("host {host:?} is not this preview server's address"),
        )
        .into_response();
    }
    // No `Origin`: not a browser's cross-site request (curl, the page's own
    // navigation). With one, it must be the page this server serves.
    if let Some(origin) = req.headers().get(header::ORIGIN) {
        let origin = origin.to_str().unwrap_or("");
        let own = origin
            .strip_prefix("http://")
            .is_some_and(|o| o.eq_ignore_ascii_case(host));
        if !own {
            return ApiError(
                StatusCode::FORBIDDEN,
                format!("origin {origin:?} is not this preview server's page"),
            )
            .into_response();
        }
    }
    next.run(req).await
}

async fn scene(State(state): State<Arc<AppState>>) -> Response {
    (no_store(), Json(&state.evaluator.scene)).into_response()
}

fn binary(bytes: Vec<u8>, content_type: &'static str) -> Response {
    (
        [
            (header::CONTENT_TYPE, HeaderValue::from_static(content_type)),
            (header::CACHE_CONTROL, HeaderValue::from_static("no-store")),
        ],
        bytes,
    )
        .into_response()
}

async fn strokes(State(state): State<Arc<AppState>>) -> Response {
    binary(state.evaluator.strokes.clone(), "application/octet-stream")
}

/// Whether a `Content-Type` is JSON: the media type `application/json`, in
/// any case (RFC 9110 §8.3.1), with parameters or none (`; charset=utf-8`);
/// not another type that begins the same (`application/jsonp`).
fn is_json(content_type: &str) -> bool {
    let media_type = content_type.split(';').next().unwrap_or_default();
    media_type.trim().eq_ignore_ascii_case("application/json")
}

/// Parses a JSON body by hand so every failure is a 400 with a message.
fn parse<T: serde::de::DeserializeOwned>(headers: &HeaderMap, body: &Bytes) -> Result<T, ApiError> {
    let json = headers
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .is_some_and(is_json);
    if !json {
        return Err(ApiError(
            StatusCode::UNSUPPORTED_MEDIA_TYPE,
            "expected Content-Type: application/json".into(),
        ));
    }
    Ok(from_json(body)?)
}

/// A request's headers and whole body, which must arrive within
/// [`BODY_TIMEOUT`]: a client that sends headers and then stalls would
/// otherwise hold its connection for ever (hyper bounds only the headers).
/// Over the body limit: axum's own 413.
struct BodyInTime(HeaderMap, Bytes);

impl<S: Send + Sync> FromRequest<S> for BodyInTime {
    type Rejection = Response;

    async fn from_request(req: Request, state: &S) -> Result<Self, Response> {
        let headers = req.headers().clone();
        match tokio::time::timeout(BODY_TIMEOUT, Bytes::from_request(req, state)).await {
            Ok(Ok(body)) => Ok(BodyInTime(headers, body)),
            Ok(Err(rejection)) => Err(rejection.into_response()),
            Err(_) => Err(ApiError(
                StatusCode::REQUEST_TIMEOUT,
                format!("the request body did not arrive within {} s", BODY_TIMEOUT.as_secs()),
            )
            .into_response()),
        }
    }
}

async fn frame(
    State(state): State<Arc<AppState>>,
    BodyInTime(headers, body): BodyInTime,
) -> Result<Response, ApiError> {
    let req: FrameRequest = parse(&headers, &body)?;
    req.check(&state.evaluator.axes)?;
    let bytes = state.evaluator.frame(req).await?;
    Ok(binary(bytes, "application/octet-stream"))
}

async fn render(
    State(state): State<Arc<AppState>>,
    BodyInTime(headers, body): BodyInTime,
) -> Result<Response, ApiError> {
    let req: RenderRequest = parse(&headers, &body)?;
    req.check(&state.evaluator.axes)?;
    let png = state.evaluator.render(req).await?;
    Ok(binary(png, "image/png"))
}

async fn ws(State(state): State<Arc<AppState>>, upgrade: WebSocketUpgrade) -> Response {
    upgrade
        .max_message_size(MAX_WS_MESSAGE)
        .max_frame_size(MAX_WS_MESSAGE)
        .on_upgrade(move |socket| stream(socket, state))
}

/// One page's slider stream: each text message is a [`FrameRequest`],
/// answered by a binary frame or a text `{"id", "status", "error"}`.
async fn stream(mut socket: WebSocket, state: Arc<AppState>) {
    // A message that came while a frame was evaluated, answered next.
    let mut next: Option<Message> = None;
    loop {
        let msg = match next.take() {
            Some(msg) => msg,
            None => match socket.recv().await {
                Some(Ok(msg)) => msg,
                _ => break,
            },
        };
        let text = match msg {
            Message::Text(t) => t,
            Message::Close(_) => break,
            Message::Ping(_) | Message::Pong(_) => continue,
            Message::Binary(_) => {
                let reply = error_message(0, StatusCode::BAD_REQUEST, "send frame requests as JSON text");
                if socket.send(reply).await.is_err() {
                    break;
                }
                continue;
            }
        };
        let reply = match from_json::<FrameRequest>(text.as_bytes()) {
            Err(BadRequest(m)) => error_message(readable_id(&text), StatusCode::BAD_REQUEST, &m),
            Ok(req) => {
                let id = req.id;
                match req.check(&state.evaluator.axes) {
                    Err(b) => error_message(id, StatusCode::BAD_REQUEST, &b.0),
                    Ok(()) => match watching(&mut socket, &mut next, state.evaluator.frame(req)).await {
                        None => break,
                        Some(Ok(bytes)) => Message::Binary(bytes.into()),
                        Some(Err(e)) => {
                            let ApiError(status, m) = e.into();
                            error_message(id, status, &m)
                        }
                    },
                }
            }
        };
        if socket.send(reply).await.is_err() {
            break;
        }
    }
}

/// Awaits `job` while watching the socket: `None` when the page closes or
/// goes first, which drops the job (the evaluator skips a request whose
/// client has gone, so a closed page's frames are not computed). One
/// message that arrives meanwhile is kept in `next`; the socket is then not
/// read again until the job is done, so a client cannot queue more here
/// than one message.
async fn watching<T>(socket: &mut WebSocket, next: &mut Option<Message>, job: impl Future<Output = T>) -> Option<T> {
    tokio::pin!(job);
    loop {
        tokio::select! {
            // The job first: its first poll queues it, so a page that has
            // gone is always seen by the evaluator as a request to skip.
            biased;
            done = &mut job => return Some(done),
            msg = socket.recv(), if next.is_none() => match msg {
                Some(Ok(Message::Ping(_) | Message::Pong(_))) => {}
                Some(Ok(Message::Close(_)) | Err(_)) | None => return None,
                Some(Ok(msg)) => *next = Some(msg),
            },
        }
    }
}

/// The `id` of a message that is JSON but not a valid request (an unknown
/// field, a wrong type elsewhere), so the page can still match the error to
/// what it sent; 0 when there is none to read.
fn readable_id(text: &str) -> u64 {
    serde_json::from_str::<serde_json::Value>(text)
        .ok()
        .and_then(|v| v.get("id")?.as_u64())
        .unwrap_or(0)
}

fn error_message(id: u64, status: StatusCode, message: &str) -> Message {
    let body = serde_json::json!({ "id": id, "status": status.as_u16(), "error": message });
    Message::Text(body.to_string().into())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn json_is_application_json_in_any_case_with_parameters() {
        for yes in [
            "application/json",
            "Application/JSON",
            "application/json; charset=utf-8",
            "APPLICATION/JSON;charset=UTF-8",
            "application/json ; charset=utf-8",
        ] {
            assert!(is_json(yes), "{yes}");
        }
        for no in [
            "application/jsonp",
            "application/json-seq",
            "application/json+x; charset=utf-8",
            "application/ld+json",
            "text/json",
            "text/plain",
            "",
        ] {
            assert!(!is_json(no), "{no}");
        }
    }
}
