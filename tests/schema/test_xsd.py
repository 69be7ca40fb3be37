"""Tests of ``grammar/imros.xsd``: it loads, documents itself and accepts exactly the grammar.

The schema carries structure and simple datatypes only; lexical and semantic rules (ids,
names, lists, patterns, expressions) belong to the Python passes and are tested there.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path

import pytest
import xmlschema
from lxml import etree

ROOT = Path(__file__).resolve().parents[2]
XSD_PATH = ROOT / "grammar" / "imros.xsd"
EXAMPLES = ROOT / "examples"
EXAMPLE_NAMES = ("water_sampling.xml", "uav_landing.xml", "crop_surveying.xml")

XS = "http://www.w3.org/2001/XMLSchema"
NS = {"xs": XS}
CITATION = re.compile(r"thesis [0-9A]")

# The 21 tags of the thesis' Appendix A, Table A.1.
TABLE_A1_TAGS = frozenset(
    {
        "imROS",
        "scope",
        "publish",
        "topic",
        "call",
        "service",
        "param",
        "arch",
        "temporal",
        "pattern",
        "condition",
        "value",
        "detect",
        "bag",
        "check",
        "success",
        "fail",
        "monitor",
        "block",
        "action",
        "violation",
    }
)

MINIMAL = '<imROS project="p"><scope><publish id="a">/t</publish></scope></imROS>'


@pytest.fixture(scope="module")
def schema() -> xmlschema.XMLSchema10:
    return xmlschema.XMLSchema10(str(XSD_PATH))


@pytest.fixture(scope="module")
def xsd_tree() -> etree._ElementTree:
    return etree.parse(str(XSD_PATH))


def _declarations(tree: etree._ElementTree, kind: str) -> list[etree._Element]:
    """Every named ``xs:element`` or ``xs:attribute`` declaration (refs have no name)."""
    return [node for node in tree.iter(f"{{{XS}}}{kind}") if node.get("name")]


def _owner(node: etree._Element) -> str:
    """Name of the element declaration that encloses ``node`` (all types are inline)."""
    for ancestor in node.iterancestors(f"{{{XS}}}element"):
        name = ancestor.get("name")
        if name:
            return name
    raise AssertionError(f"declaration {node.get('name')!r} outside any element")


def _example_elements() -> Iterator[etree._Element]:
    for name in EXAMPLE_NAMES:
        root = etree.parse(str(EXAMPLES / name)).getroot()
        for node in root.iter():
            if isinstance(node.tag, str):  # skip comments and processing instructions
                yield node


def test_xsd_loads_as_xsd_1_0_without_namespace(
    schema: xmlschema.XMLSchema10, xsd_tree: etree._ElementTree
) -> None:
    assert schema.XSD_VERSION == "1.0"
    assert xsd_tree.getroot().get("targetNamespace") is None
    assert list(schema.elements) == ["imROS"]


def test_xsd_starts_with_a_header_comment() -> None:
    text = XSD_PATH.read_text(encoding="utf-8")
    body = text.split("?>", 1)[1].lstrip() if text.startswith("<?xml") else text
    assert body.startswith("<!--")
    assert "imROS" in body.split("-->", 1)[0]


@pytest.mark.parametrize("name", EXAMPLE_NAMES)
def test_examples_validate(schema: xmlschema.XMLSchema10, name: str) -> None:
    schema.validate(str(EXAMPLES / name))


@pytest.mark.parametrize("name", EXAMPLE_NAMES)
def test_examples_have_a_header_comment(name: str) -> None:
    first = (EXAMPLES / name).read_text(encoding="utf-8").lstrip()
    assert first.startswith("<!--")
    assert "thesis" in first.split("-->", 1)[0]


@pytest.mark.parametrize("kind", ["element", "attribute"])
def test_every_declaration_is_documented_with_a_thesis_section(
    xsd_tree: etree._ElementTree, kind: str
) -> None:
    declarations = _declarations(xsd_tree, kind)
    assert declarations
    for node in declarations:
        docs = node.findall("xs:annotation/xs:documentation", NS)
        text = " ".join(str(doc.xpath("string()")) for doc in docs).strip()
        assert text, f"{kind} {node.get('name')!r} has no documentation"
        assert CITATION.search(text), f"{kind} {node.get('name')!r} cites no thesis section"


def test_all_table_a1_tags_are_declared(xsd_tree: etree._ElementTree) -> None:
    declared = {node.get("name") for node in _declarations(xsd_tree, "element")}
    assert len(TABLE_A1_TAGS) == 21
    assert declared == TABLE_A1_TAGS


def test_examples_use_every_declared_name(xsd_tree: etree._ElementTree) -> None:
    elements = {str(node.get("name")) for node in _declarations(xsd_tree, "element")}
    attributes = {str(node.get("name")) for node in _declarations(xsd_tree, "attribute")}
    used_elements: set[str] = set()
    used_attributes: set[str] = set()
    for node in _example_elements():
        used_elements.add(etree.QName(node).localname)
        used_attributes.update(str(key) for key in node.attrib)
    assert elements - used_elements == set()
    assert attributes - used_attributes == set()


def test_examples_use_every_declared_placement(xsd_tree: etree._ElementTree) -> None:
    """Stronger than names: every (parent, child) and (element, attribute) declared is used."""
    children = {
        (_owner(node), str(node.get("name")))
        for node in _declarations(xsd_tree, "element")
        if node.get("name") != "imROS"
    }
    attributes = {
        (_owner(node), str(node.get("name"))) for node in _declarations(xsd_tree, "attribute")
    }
    used_children: set[tuple[str, str]] = set()
    used_attributes: set[tuple[str, str]] = set()
    for node in _example_elements():
        tag = etree.QName(node).localname
        used_attributes.update((tag, str(key)) for key in node.attrib)
        parent = node.getparent()
        if parent is not None:
            used_children.add((etree.QName(parent).localname, tag))
    assert children - used_children == set()
    assert attributes - used_attributes == set()


def test_examples_use_text_and_child_forms_of_names() -> None:
    """<publish> and <call> appear both with their name as text and as child elements."""
    forms: set[tuple[str, bool]] = set()
    for node in _example_elements():
        tag = etree.QName(node).localname
        if tag in ("publish", "call"):
            forms.add((tag, bool((node.text or "").strip())))
    assert forms == {("publish", True), ("publish", False), ("call", True), ("call", False)}


def test_minimal_document_is_valid(schema: xmlschema.XMLSchema10) -> None:
    assert schema.is_valid(MINIMAL)


def test_defaults_of_tunables(schema: xmlschema.XMLSchema10) -> None:
    doc = (
        '<imROS project="p"><scope><temporal id="e" events="a"/></scope>'
        '<detect inv="x.inv"><bag>b</bag></detect><check/><monitor/></imROS>'
    )
    data = schema.to_dict(doc)
    assert isinstance(data, dict)
    detect, check, monitor = data["detect"], data["check"], data["monitor"]
    temporal = data["scope"]["temporal"][0]
    assert float(detect["@window"]) == 1.0
    assert float(detect["@confidence"]) == 0.99
    assert float(detect["@drop_ratio"]) == 0.9
    assert detect["@hull_chunk"] == 20
    assert detect["@discrete"] == 10
    assert detect["@step_tail"] == "select"
    assert float(temporal["@max_interval"]) == 2.0
    assert temporal["@max_events"] == 10
    assert float(check["@threshold"]) == 0.5
    assert float(check["@beta"]) == 1.0
    assert float(monitor["@period"]) == 1.0


@pytest.mark.parametrize(
    "doc",
    [
        pytest.param(
            '<imROS project="p"><scope><publish id="a">/t</publish><bogus/></scope></imROS>',
            id="unknown-element",
        ),
        pytest.param(
            '<imROS project="p"><scope><publish id="a" colour="red">/t</publish></scope></imROS>',
            id="unknown-attribute",
        ),
        pytest.param(
            '<imROS project="p"><scope><publish id="a" relative="x">/t</publish></scope></imROS>',
            id="relative-not-integer",
        ),
        pytest.param(
            '<imROS><scope><publish id="a">/t</publish></scope></imROS>',
            id="missing-project",
        ),
        pytest.param('<imROS project="p"/>', id="missing-scope"),
        pytest.param('<imROS project="p"><scope/></imROS>', id="empty-scope"),
        pytest.param(
            '<imROS project="p"><scope><publish>/t</publish></scope></imROS>',
            id="publish-without-id",
        ),
        pytest.param(
            '<imROS project="p"><scope><param id="a">/x</param></scope><detect inv="x"/></imROS>',
            id="detect-without-bag",
        ),
        pytest.param(
            '<imROS project="p"><scope><param>/x</param></scope>'
            '<detect inv="x" confidence="1"><bag>b</bag></detect></imROS>',
            id="confidence-one",
        ),
        pytest.param(
            '<imROS project="p"><scope><param>/x</param></scope><check threshold="1.5"/></imROS>',
            id="threshold-above-one",
        ),
        pytest.param(
            '<imROS project="p"><scope><param>/x</param></scope><monitor period="0"/></imROS>',
            id="period-zero",
        ),
        pytest.param(
            '<imROS project="p"><scope><publish id="a"><param id="b">/x</param></publish>'
            "</scope></imROS>",
            id="id-on-publish-param",
        ),
        pytest.param(
            '<imROS project="p"><scope><param>/x</param></scope>'
            '<monitor><action id="f"><value>{}</value></action></monitor></imROS>',
            id="action-without-target",
        ),
        pytest.param(
            '<imROS project="p"><scope><condition id="1"><value>x</value></condition>'
            "</scope></imROS>",
            id="condition-without-topic",
        ),
        pytest.param(
            '<imROS project="p"><scope><param>/x</param></scope><scope><param>/y</param>'
            "</scope></imROS>",
            id="two-scopes",
        ),
    ],
)
def test_invalid_documents_are_rejected(schema: xmlschema.XMLSchema10, doc: str) -> None:
    assert not schema.is_valid(doc)
