//! The routes: which handler answers which method and path, and the fallbacks.

use axum::Router;
use axum::body::Body;
use axum::extract::{DefaultBodyLimit, Request, State};
use axum::http::{HeaderValue, Method, StatusCode, Version, header};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};

use crate::app::App;
use crate::error::ApiError;
use crate::guard::add_security_headers;
use crate::limits::read_body;
use crate::{api, device_api, pages};

/// The largest request body (a frame, a fault): anything larger is refused with 413.
pub const MAX_BODY: usize = 4096;

pub fn router(app: App) -> Router {
    Router::new()
        .route("/", get(pages::overview))
        .route("/ids", get(pages::ids))
        .route("/frames", get(pages::frames))
        .route("/signals", get(pages::signals))
        .route("/nodes/{number}", get(pages::node))
        .route("/dashboard", get(pages::dashboard))
        .route("/assets/{name}", get(pages::asset))
        .route("/api/state", get(api::state))
        .route("/api/events", get(api::events))
        .route("/api/send", post(api::send))
        .route("/api/fault", post(api::fault))
        .route("/api/repair", post(api::repair))
        .route("/devices", get(pages::devices))
        .route("/api/devices", get(device_api::devices))
        .route("/api/slio", post(device_api::slio))
        .route("/api/zelle", post(device_api::zelle))
        .route("/api/cpu196", post(device_api::cpu196))
        .fallback(not_found)
        .method_not_allowed_fallback(method_not_allowed)
        .layer(DefaultBodyLimit::max(MAX_BODY))
        .layer(middleware::from_fn_with_state(app.clone(), admit))
        .layer(middleware::map_response(secure))
        .with_state(app)
}

/// Every answer, refusals included, says what a browser may do with it.
async fn secure(mut response: Response) -> Response {
    add_security_headers(response.headers_mut());
    response
}

/// Before any route: the request names a host this server answers to, a write comes from
/// one of its pages (when it comes from a page at all), and the body arrives whole, in time
/// and within [`MAX_BODY`].
async fn admit(State(app): State<App>, request: Request, next: Next) -> Response {
    let (parts, body) = request.into_parts();
    let host = parts.headers.get(header::HOST).map(HeaderValue::as_bytes);
    let http11 = parts.version >= Version::HTTP_11;
    if let Err(e) = app.hosts.check_host(host, http11) {
        return e.into_response();
    }
    // An absolute-form target (`GET http://name/ HTTP/1.1`) names its host too.
    if let Some(authority) = parts.uri.authority()
        && let Err(e) = app
            .hosts
            .check_host(Some(authority.as_str().as_bytes()), http11)
    {
        return e.into_response();
    }
    let write = !matches!(parts.method, Method::GET | Method::HEAD);
    if write
        && let Some(origin) = parts.headers.get(header::ORIGIN)
        && let Err(e) = app.hosts.check_origin(origin.as_bytes())
    {
        return e.into_response();
    }
    match read_body(body, MAX_BODY, app.timeouts.request).await {
        Ok(bytes) => {
            next.run(Request::from_parts(parts, Body::from(bytes)))
                .await
        }
        Err(e) => {
            let mut response = e.into_response();
            // What is left of the body may never come: the connection cannot be reused.
            response
                .headers_mut()
                .insert(header::CONNECTION, HeaderValue::from_static("close"));
            response
        }
    }
}

async fn not_found() -> ApiError {
    ApiError::new(
        StatusCode::NOT_FOUND,
        "no such page: see / for the pages and docs/web.md for the API",
    )
}

async fn method_not_allowed() -> ApiError {
    ApiError::new(
        StatusCode::METHOD_NOT_ALLOWED,
        "method not allowed here: pages are GET, writes are POST to /api/send, /api/fault, \
         /api/repair, /api/slio, /api/zelle, /api/cpu196",
    )
}
