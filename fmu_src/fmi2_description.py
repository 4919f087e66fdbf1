"""FMI 3.0 modelDescription.xml of a featherstar FMU -> the FMI 2.0 one of the same model.

The FMI 2.0 build runs the same C shell behind an FMI 2.0 adapter (c/fmi2_adapter.c) that passes
value references through unchanged, so the FMI 2.0 description lists the same variables with the
same value references, units, ranges and descriptions. What changes is the form: <ScalarVariable>
with a <Real> child, `guid` for `instantiationToken`, `derivative` and `dependencies` as 1-based
indices into <ModelVariables> instead of value references, and <ModelStructure> as
<Outputs>/<Derivatives>/<InitialUnknowns> lists. `time` is not declared: FMI 2.0 importers keep
time themselves.
"""
from __future__ import annotations

import xml.etree.ElementTree as ET

from .errors import BuildError

#: Attributes of an FMI 3.0 <Float64> that go to the FMI 2.0 <ScalarVariable>, and to its <Real>.
_VARIABLE_ATTRIBUTES = ("name", "valueReference", "description", "causality", "variability", "initial")
_REAL_ATTRIBUTES = ("declaredType", "quantity", "unit", "displayUnit", "relativeQuantity", "min", "max",
                    "nominal", "unbounded", "start")
_CAPABILITIES = {  # FMI 3.0 attribute -> FMI 2.0 attribute, on <ModelExchange>/<CoSimulation>
    "modelIdentifier": "modelIdentifier",
    "canHandleVariableCommunicationStepSize": "canHandleVariableCommunicationStepSize",
    "canGetAndSetFMUState": "canGetAndSetFMUstate",
    "canSerializeFMUState": "canSerializeFMUstate",
    "providesDirectionalDerivatives": "providesDirectionalDerivative",
}


def fmi2_model_description(fmi3_text: str) -> str:
    """The FMI 2.0 modelDescription.xml text for a featherstar FMI 3.0 one. Raises BuildError."""
    root3 = ET.fromstring(fmi3_text)
    if root3.get("fmiVersion") != "3.0":
        raise BuildError(f"expected an FMI 3.0 modelDescription.xml, got fmiVersion={root3.get('fmiVersion')!r}")
    variables = [v for v in root3.find("ModelVariables") if v.get("causality") != "independent"]
    unsupported = [f"{v.tag} '{v.get('name')}'" for v in variables if v.tag != "Float64"]
    if unsupported:
        raise BuildError(f"FMI 2.0 export handles Float64 variables only, not {', '.join(unsupported)}")
    index_of_vr = {v.get("valueReference"): i + 1 for i, v in enumerate(variables)}

    root = ET.Element("fmiModelDescription", {
        "fmiVersion": "2.0",
        "modelName": root3.get("modelName", ""),
        "guid": root3.get("instantiationToken", ""),
        "description": root3.get("description", ""),
        "generationTool": f"featherstar (FMI 2.0 adapter over {root3.get('generationTool', 'CasADi')})",
        "generationDateAndTime": root3.get("generationDateAndTime", ""),
        "variableNamingConvention": root3.get("variableNamingConvention", "flat"),
        "numberOfEventIndicators": str(len(root3.findall("ModelStructure/EventIndicator"))),
    })
    for interface in ("ModelExchange", "CoSimulation"):
        element = root3.find(interface)
        if element is None:
            continue
        attributes = {_CAPABILITIES[k]: v for k, v in element.attrib.items() if k in _CAPABILITIES}
        if interface == "ModelExchange":  # FMI 2.0 says the opposite, and defaults to "needed"
            attributes["completedIntegratorStepNotNeeded"] = str(
                element.get("needsCompletedIntegratorStep") != "true").lower()
        ET.SubElement(root, interface, attributes)
    for section in ("UnitDefinitions", "LogCategories", "DefaultExperiment"):
        element = root3.find(section)
        if element is not None:
            root.append(element)

    model_variables = ET.SubElement(root, "ModelVariables")
    for v in variables:
        scalar = ET.SubElement(model_variables, "ScalarVariable",
                               {k: v.get(k) for k in _VARIABLE_ATTRIBUTES if v.get(k) is not None})
        if scalar.get("causality") in ("parameter", "input", "output", "local", None):
            scalar.set("variability", v.get("variability", "continuous"))
        if scalar.get("causality") == "input":  # FMI 2.0 inputs carry no `initial`
            scalar.attrib.pop("initial", None)
        real = ET.SubElement(scalar, "Real", {k: v.get(k) for k in _REAL_ATTRIBUTES if v.get(k) is not None})
        if v.get("derivative"):
            real.set("derivative", str(index_of_vr[v.get("derivative")]))

    def unknowns(parent: ET.Element, tag: str, kind: str) -> None:
        # FMI 2.0 wants each list ordered by index.
        listed = sorted(root3.findall(f"ModelStructure/{kind}"), key=lambda u: index_of_vr[u.get("valueReference")])
        for unknown in listed:
            attributes = {"index": str(index_of_vr[unknown.get("valueReference")])}
            dependencies = unknown.get("dependencies")
            if dependencies is not None:
                attributes["dependencies"] = " ".join(str(index_of_vr[d]) for d in dependencies.split())
            ET.SubElement(parent, tag, attributes)

    structure = ET.SubElement(root, "ModelStructure")
    for section, kind in (("Outputs", "Output"), ("Derivatives", "ContinuousStateDerivative"),
                          ("InitialUnknowns", "InitialUnknown")):
        if root3.find(f"ModelStructure/{kind}") is not None:
            unknowns(ET.SubElement(structure, section), "Unknown", kind)
    ET.indent(root, space="    ")
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode")
