//! The page's files, embedded in the binary at build time: served by exact name from this
//! table only, so no part of a URL ever reaches the filesystem, and nothing is fetched at run
//! time (uPlot is vendored, see `assets/VENDORED.md`).

/// One embedded file.
#[derive(Debug, Clone, Copy)]
pub struct Asset {
    /// Its name under `/assets/`.
    pub name: &'static str,
    /// `Content-Type`.
    pub content_type: &'static str,
    /// The bytes.
    pub bytes: &'static [u8],
}

macro_rules! asset {
    ($name:literal, $ty:literal) => {
        Asset {
            name: $name,
            content_type: $ty,
            bytes: include_bytes!(concat!("../assets/", $name)),
        }
    };
}

/// Every embedded file.
pub const ASSETS: &[Asset] = &[
    asset!("index.html", "text/html; charset=utf-8"),
    asset!("pipeline.html", "text/html; charset=utf-8"),
    asset!("studies.html", "text/html; charset=utf-8"),
    asset!("app.js", "text/javascript; charset=utf-8"),
    asset!("pipeline.js", "text/javascript; charset=utf-8"),
    asset!("studies.js", "text/javascript; charset=utf-8"),
    asset!("dom.js", "text/javascript; charset=utf-8"),
    asset!("style.css", "text/css; charset=utf-8"),
    asset!("favicon.svg", "image/svg+xml"),
    asset!("uPlot.iife.min.js", "text/javascript; charset=utf-8"),
    asset!("uPlot.min.css", "text/css; charset=utf-8"),
    asset!("uPlot.LICENSE", "text/plain; charset=utf-8"),
];

/// The asset named `name`, if embedded.
pub fn get(name: &str) -> Option<&'static Asset> {
    ASSETS.iter().find(|a| a.name == name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_embedded_names_resolve() {
        assert!(get("app.js").is_some_and(|a| !a.bytes.is_empty()));
        for bad in [
            "../Cargo.toml",
            "/etc/passwd",
            "assets/app.js",
            "",
            "APP.JS",
            "app.js/",
        ] {
            assert!(get(bad).is_none(), "{bad}");
        }
    }

    #[test]
    fn the_pages_load_only_embedded_scripts_and_styles() {
        for page in ["index.html", "pipeline.html", "studies.html"] {
            let text = std::str::from_utf8(get(page).unwrap().bytes).unwrap();
            for attr in ["src=\"", "href=\""] {
                for part in text.split(attr).skip(1) {
                    let url = part.split('"').next().unwrap();
                    if let Some(name) = url.strip_prefix("/assets/") {
                        assert!(get(name).is_some(), "{page} loads missing asset {url}");
                    } else {
                        assert!(
                            url.starts_with('/') || url.starts_with('#'),
                            "{page} refers outside the server: {url}"
                        );
                    }
                }
            }
        }
    }
}
