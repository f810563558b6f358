//! The page's files, embedded in the binary at build time: served by exact name from this
//! table only, so no part of a URL ever reaches the filesystem, and nothing is fetched at run
//! time (uPlot is vendored, see `assets/VENDORED.md`). The pages' scripts are ES modules
//! (`<script type="module">`, which browsers run only when served as JavaScript): the design
//! explorer's is `main.js` and what it imports, every one listed in [`MODULES`].

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
    ($name:literal, $ty:expr) => {
        Asset {
            name: $name,
            content_type: $ty,
            bytes: include_bytes!(concat!("../assets/", $name)),
        }
    };
}

/// `Content-Type` of the scripts (module scripts require a JavaScript MIME type).
const JS: &str = "text/javascript; charset=utf-8";

/// The pages' ES modules.
pub const MODULES: &[Asset] = &[
    asset!("main.js", JS),
    asset!("state.js", JS),
    asset!("api.js", JS),
    asset!("codec.js", JS),
    asset!("format.js", JS),
    asset!("series.js", JS),
    asset!("verdicts.js", JS),
    asset!("ui.js", JS),
    asset!("inputs.js", JS),
    asset!("tables.js", JS),
    asset!("charts.js", JS),
    asset!("sweep.js", JS),
    asset!("studies-start.js", JS),
    asset!("dom.js", JS),
    asset!("pipeline.js", JS),
    asset!("studies.js", JS),
];

/// Every other embedded file.
const FILES: &[Asset] = &[
    asset!("index.html", "text/html; charset=utf-8"),
    asset!("pipeline.html", "text/html; charset=utf-8"),
    asset!("studies.html", "text/html; charset=utf-8"),
    asset!("style.css", "text/css; charset=utf-8"),
    asset!("favicon.svg", "image/svg+xml"),
    asset!("uPlot.iife.min.js", JS),
    asset!("uPlot.min.css", "text/css; charset=utf-8"),
    asset!("uPlot.LICENSE", "text/plain; charset=utf-8"),
];

/// The asset named `name`, if embedded.
pub fn get(name: &str) -> Option<&'static Asset> {
    MODULES.iter().chain(FILES).find(|a| a.name == name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_embedded_names_resolve() {
        assert!(get("main.js").is_some_and(|a| !a.bytes.is_empty()));
        for bad in [
            "../Cargo.toml",
            "/etc/passwd",
            "assets/main.js",
            "",
            "MAIN.JS",
            "main.js/",
            "app.js",
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

    #[test]
    fn every_module_imports_only_embedded_modules_and_is_served_as_javascript() {
        for module in MODULES {
            assert_eq!(module.content_type, JS, "{}", module.name);
            let text = std::str::from_utf8(module.bytes).unwrap();
            assert!(
                text.starts_with("/*"),
                "{} opens without its comment",
                module.name
            );
            for line in text.lines() {
                let Some(from) = line.split(" from '").nth(1) else {
                    continue;
                };
                let spec = from.split('\'').next().unwrap();
                let name = spec.strip_prefix("./").unwrap_or_else(|| {
                    panic!(
                        "{} imports {spec}: only ./NAME of the embedded modules",
                        module.name
                    )
                });
                assert!(
                    MODULES.iter().any(|m| m.name == name),
                    "{} imports {spec}, which is not an embedded module",
                    module.name
                );
            }
        }
        for page in ["index.html", "pipeline.html", "studies.html"] {
            let text = std::str::from_utf8(get(page).unwrap().bytes).unwrap();
            for part in text.split("<script").skip(1) {
                let tag = part.split('>').next().unwrap();
                if tag.contains("uPlot") {
                    continue;
                }
                let src = tag
                    .split("src=\"/assets/")
                    .nth(1)
                    .unwrap()
                    .split('"')
                    .next()
                    .unwrap();
                assert!(
                    tag.contains("type=\"module\"") && MODULES.iter().any(|m| m.name == src),
                    "{page}: {tag}"
                );
            }
        }
    }
}
