//! The rules `painterly inspect` checks, each with a stable id.
//!
//! An [`Error`](crate::Error) found while reading a character may name the
//! rule it breaks; `inspect --json` prints it with every problem, and the
//! Python package's UsdValidation plugin registers one validator per rule
//! (named [`Rule::validator`]) that reports the problems with that id. The
//! checks themselves live where the stage is read; this list only names
//! them, so the CLI and the validators can never disagree.

use std::fmt;

/// One rule of the painterly schema that a stage can break.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Rule {
    MissingProxy,
    Mesh,
    Skinning,
    LayerOutsideRig,
    LayerNotCurves,
    PointCounts,
    MissingRestPoints,
    Binding,
    DisplayOpacity,
    Axis,
    KeyPointCounts,
    KeyCoordinates,
    KeyTime,
    CoincidentKeys,
    SentinelMisuse,
    Interpolation,
    ViewMesh,
    ViewKeyCounts,
    ViewKeyDirections,
    ViewKeyTimes,
    NonFinite,
    AttributeType,
    Chunks,
    Instanced,
    Unreadable,
}

impl Rule {
    /// Every rule, in the order the docs list them.
    pub const ALL: [Rule; 25] = [
        Rule::MissingProxy,
        Rule::Mesh,
        Rule::Skinning,
        Rule::LayerOutsideRig,
        Rule::LayerNotCurves,
        Rule::PointCounts,
        Rule::MissingRestPoints,
        Rule::Binding,
        Rule::DisplayOpacity,
        Rule::Axis,
        Rule::KeyPointCounts,
        Rule::KeyCoordinates,
        Rule::KeyTime,
        Rule::CoincidentKeys,
        Rule::SentinelMisuse,
        Rule::Interpolation,
        Rule::ViewMesh,
        Rule::ViewKeyCounts,
        Rule::ViewKeyDirections,
        Rule::ViewKeyTimes,
        Rule::NonFinite,
        Rule::AttributeType,
        Rule::Chunks,
        Rule::Instanced,
        Rule::Unreadable,
    ];

    /// The stable id (`inspect --json` prints it as a problem's `rule`).
    pub fn id(self) -> &'static str {
        self.describe().0
    }

    /// The UsdValidation validator's name (`painterly:<name>` in the registry).
    pub fn validator(self) -> &'static str {
        self.describe().1
    }

    /// What the rule asks of a stage, one sentence.
    pub fn doc(self) -> &'static str {
        self.describe().2
    }

    /// The rule with this id.
    pub fn from_id(id: &str) -> Option<Rule> {
        Rule::ALL.into_iter().find(|r| r.id() == id)
    }

    fn describe(self) -> (&'static str, &'static str, &'static str) {
        match self {
            Rule::MissingProxy => (
                "missing-proxy",
                "MissingProxy",
                "A rig's painterly:proxy names exactly one existing Mesh.",
            ),
            Rule::Mesh => (
                "mesh",
                "Mesh",
                "A proxy or view-dependent mesh has faces, in-range indices and rest points.",
            ),
            Rule::Skinning => (
                "skinning",
                "Skinning",
                "A skinned proxy or view-dependent mesh has a UsdSkel binding painterly can evaluate.",
            ),
            Rule::LayerOutsideRig => (
                "layer-outside-rig",
                "LayerOutsideRig",
                "A stroke layer sits under a prim with PainterlyRigAPI.",
            ),
            Rule::LayerNotCurves => (
                "layer-not-curves",
                "LayerNotCurves",
                "PainterlyStrokeLayerAPI is applied to BasisCurves only.",
            ),
            Rule::PointCounts => (
                "point-counts",
                "PointCounts",
                "A stroke layer's curveVertexCounts, points and painterly:restPoints agree in count.",
            ),
            Rule::MissingRestPoints => (
                "missing-rest-points",
                "MissingRestPoints",
                "A stroke layer has painterly:restPoints or a default value of points.",
            ),
            Rule::Binding => (
                "binding",
                "Binding",
                "A cached binding (painterly:bindVertices, painterly:bindWeights) has one in-range entry per point, with barycentric weights (each in [0, 1], summing to 1).",
            ),
            Rule::DisplayOpacity => (
                "display-opacity",
                "DisplayOpacity",
                "primvars:displayOpacity has 1, one-per-curve, one-per-point or (varying) one-per-segment-end values and valid indices; it, painterly:opacity and key opacities lie in [0, 1].",
            ),
            Rule::Axis => (
                "axis",
                "Axis",
                "A layer's axes exist and each PainterlyAxis has a valid kind, source, name and component.",
            ),
            Rule::KeyPointCounts => (
                "key-point-counts",
                "KeyPointCounts",
                "A pose or time key's points has one point per point of its layer.",
            ),
            Rule::KeyCoordinates => (
                "key-coordinates",
                "KeyCoordinates",
                "A pose key has coordinates, one per axis of its layer; a time key has none (they would be ignored).",
            ),
            Rule::KeyTime => (
                "key-time",
                "KeyTime",
                "A time key has a time; a pose key has none (it would be ignored).",
            ),
            Rule::CoincidentKeys => (
                "coincident-keys",
                "CoincidentKeys",
                "No two keys of one channel share coordinates (pose keys) or a time (time keys).",
            ),
            Rule::SentinelMisuse => (
                "sentinel-misuse",
                "SentinelMisuse",
                "A sentinel time key carries no points or opacity, and a pose key no sentinel (they would be ignored).",
            ),
            Rule::Interpolation => (
                "interpolation",
                "Interpolation",
                "painterly:interpolation is smoothVoronoi, rbf or shepard, with a positive painterly:rbfRadius.",
            ),
            Rule::ViewMesh => (
                "view-mesh",
                "ViewMesh",
                "PainterlyViewDependentAPI is on a Mesh with a positive sharpness, a known uncovered mode and a painterly:camera that targets a prim with a transform.",
            ),
            Rule::ViewKeyCounts => (
                "view-key-counts",
                "ViewKeyCounts",
                "A view key has points, one per point of its mesh.",
            ),
            Rule::ViewKeyDirections => (
                "view-key-directions",
                "ViewKeyDirections",
                "View keys have non-zero directions; key viewpoints have distinct directions.",
            ),
            Rule::ViewKeyTimes => (
                "view-key-times",
                "ViewKeyTimes",
                "The keys of one viewpoint all have distinct times, or it has one key without a time.",
            ),
            Rule::NonFinite => (
                "non-finite",
                "NonFinite",
                "Points, opacities, times and coordinates are finite.",
            ),
            Rule::AttributeType => (
                "attribute-type",
                "AttributeType",
                "Every attribute painterly reads has the type the schema gives it.",
            ),
            Rule::Chunks => (
                "chunks",
                "Chunks",
                "Every chunk of a clip-set bake is on disk and baked from the current input.",
            ),
            Rule::Instanced => (
                "instanced",
                "Instanced",
                "No rig, stroke layer or view-dependent mesh lies inside an instance (USD ignores a bake's opinions below one).",
            ),
            Rule::Unreadable => (
                "unreadable",
                "Unreadable",
                "painterly can open the stage and read what it needs (read failures no other rule covers).",
            ),
        }
    }
}

impl fmt::Display for Rule {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.id())
    }
}

impl serde::Serialize for Rule {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.id())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_and_validator_names_are_unique_and_round_trip() {
        let mut ids: Vec<_> = Rule::ALL.iter().map(|r| r.id()).collect();
        let mut names: Vec<_> = Rule::ALL.iter().map(|r| r.validator()).collect();
        ids.sort_unstable();
        names.sort_unstable();
        ids.dedup();
        names.dedup();
        assert_eq!(ids.len(), Rule::ALL.len());
        assert_eq!(names.len(), Rule::ALL.len());
        for r in Rule::ALL {
            assert_eq!(Rule::from_id(r.id()), Some(r));
            // Shown as its id, as in `--json` and the validators' names.
            assert_eq!(r.to_string(), r.id());
            // The validator name is the id in CamelCase.
            let camel: String = r.id().split('-').map(|w| w[..1].to_uppercase() + &w[1..]).collect();
            assert_eq!(camel, r.validator());
            assert!(r.doc().ends_with('.'), "{r}");
        }
    }
}
