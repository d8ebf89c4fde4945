//! Why a frame was judged lost, by the names the docs and the JS API use.

/// Why a frame was judged lost.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LostReason {
    /// Too few correspondences with the model.
    TooFewInliers,
    /// The alignment residual stayed high.
    HighResidual,
    /// The geometry does not constrain all six degrees of freedom.
    IllConditioned,
    /// The estimated motion since the last frame is implausibly large.
    ImplausibleMotion,
    /// The dense result disagrees with an independent check (the sparse
    /// feature estimate, or points landing in the model's free space).
    Inconsistent,
}

impl LostReason {
    /// Every reason, in declaration order: what the docs must name (a test
    /// checks that `docs/js-api.md`, the package README and its typings
    /// list each).
    pub const ALL: [Self; 5] = [
        Self::TooFewInliers,
        Self::HighResidual,
        Self::IllConditioned,
        Self::ImplausibleMotion,
        Self::Inconsistent,
    ];

    /// Short kebab-case name (`too-few-inliers`, ...).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::TooFewInliers => "too-few-inliers",
            Self::HighResidual => "high-residual",
            Self::IllConditioned => "ill-conditioned",
            Self::ImplausibleMotion => "implausible-motion",
            Self::Inconsistent => "inconsistent",
        }
    }
}

#[cfg(test)]
mod lost_reason_docs {
    use super::LostReason;

    /// The names `LostReason::name` can return, read from its source: its
    /// match is exhaustive, so this is every reason the code has, whether
    /// or not [`LostReason::ALL`] was kept up to date.
    fn names_in_source() -> Vec<&'static str> {
        let source = include_str!("lost_reason.rs");
        let start = source.find("impl LostReason {").unwrap_or(0);
        let body = &source[start..];
        let body = &body[body.find("fn name(self)").unwrap_or(0)..];
        let body = &body[..body.find("\n    }\n").unwrap_or(body.len())];
        body.lines()
            .filter_map(|l| l.trim().strip_prefix("Self::"))
            .filter_map(|l| l.split('"').nth(1))
            .collect()
    }

    #[test]
    fn every_loss_reason_is_in_the_docs() {
        let names: Vec<&str> = LostReason::ALL.iter().map(|r| r.name()).collect();
        assert_eq!(names, names_in_source(), "LostReason::ALL lacks a reason");
        for (file, text) in [
            ("docs/js-api.md", include_str!("../../docs/js-api.md")),
            (
                "pkg-config/README.md",
                include_str!("../../pkg-config/README.md"),
            ),
            // The package's TypeScript typings (FrameReport.lostReason).
            ("src/wasm/convert.rs", include_str!("../wasm/convert.rs")),
        ] {
            for reason in LostReason::ALL {
                let quoted = format!("'{}'", reason.name());
                assert!(
                    text.contains(&quoted),
                    "{file} does not name the loss reason {quoted}"
                );
            }
        }
    }
}
