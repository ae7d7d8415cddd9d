"""The XML document of a Mitsuba scene: elements with their file and line (``Node``),
the parser (expat, no entities), ``<include>``, ``<default>`` and ``$name``, ``id`` and
``<ref>``, the version and the older tags.
"""

from __future__ import annotations

import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from xml.parsers import expat

from radiosity.files.errors import InputError, SceneWarning
from radiosity.files.inputs import MAX_NESTING, TEXT_BYTES, check_input_file, read_input_bytes

MAX_INCLUDES = 16  # nested <include> depth
MAX_INCLUDED = 256  # <include>s read in all (each including the next ten times, eight deep, is 10^8 of them)




@dataclass
class Node:
    """One XML element: tag, attributes, children, and where it is (file, line)."""

    tag: str
    attrs: dict
    file: str
    line: int
    children: list = field(default_factory=list)

    @property
    def where(self):
        kind = f" type={self.attrs['type']!r}" if "type" in self.attrs else ""
        name = f" name={self.attrs['name']!r}" if "name" in self.attrs else ""
        return f"{self.file}:{self.line}: <{self.tag}{kind}{name}>"

    def fail(self, problem):
        return InputError(f"{self.where}: {problem}")

    def warn(self, what):
        warnings.warn(f"{self.where}: {what}", SceneWarning, stacklevel=3)


def _parse_xml(path):
    """The root Node of an XML file, with line numbers (expat, which refuses entity
    expansion bombs); InputError naming the file and line of a syntax error."""
    data = read_input_bytes(path, "scene", TEXT_BYTES)
    shown = str(path)
    parser = expat.ParserCreate()
    stack = [Node("#document", {}, shown, 0)]

    def start(tag, attrs):
        node = Node(tag, dict(attrs), shown, parser.CurrentLineNumber)
        if len(stack) > MAX_NESTING:
            raise node.fail(f"elements nested more than {MAX_NESTING} deep")
        stack[-1].children.append(node)
        stack.append(node)

    def end(_tag):
        stack.pop()

    parser.StartElementHandler, parser.EndElementHandler = start, end
    try:
        parser.Parse(data, True)
    except expat.ExpatError as exc:
        raise InputError(f"{shown}:{exc.lineno}: malformed XML: {expat.errors.messages[exc.code]}") from None
    roots = stack[0].children
    if len(roots) != 1 or roots[0].tag != "scene":
        raise InputError(f"{shown}: not a Mitsuba scene (the root element must be <scene>)")
    return roots[0]


def _snake(name):
    """Mitsuba 0.x's camelCase property names in 2-3's spelling: toWorld -> to_world,
    intIOR -> int_ior, fovAxis -> fov_axis."""
    name = re.sub(r"([a-z0-9])([A-Z])", r"\1_\2", name)
    return re.sub(r"([A-Z]+)([A-Z][a-z])", r"\1_\2", name).lower()


_PARAMETER = re.compile(r"\$([A-Za-z_][A-Za-z0-9_]*)")


class _Document:
    """A scene's elements after includes, ``$name`` substitution and ids."""

    def __init__(self, path):
        self.path = Path(path)
        self.base = self.path.parent
        root = _parse_xml(self.path)
        self.version = root.attrs.get("version", "")
        self.major = _major_version(root)
        self.params = {}
        for node in root.children:
            if node.tag == "default":
                name, value = node.attrs.get("name"), node.attrs.get("value")
                if name is None or value is None:
                    raise node.fail("needs 'name' and 'value'")
                self.params.setdefault(name, value)
        self.included = 0
        self.elements = self._expand(root.children, 0)
        if self.major < 2:
            _upgrade(self.elements)
        self.bitmaps = {}  # id(<texture> element) -> its _Bitmap, each file read once
        self.surfaces = {}  # id(<bsdf> element) -> its _Surface, made once for every shape that refers to it
        self.ids = {}
        for node in self._walk(self.elements):
            if "id" in node.attrs and node.tag != "ref":
                first = self.ids.setdefault(node.attrs["id"], node)
                if first is not node:  # Mitsuba refuses a second element of one id too
                    raise node.fail(f"id {node.attrs['id']!r} is given twice (first at {first.where})")
        self.building = set()  # the <bsdf> elements whose surfaces are being made (a cycle of refs meets one)

    def _walk(self, nodes):
        for node in nodes:
            yield node
            yield from self._walk(node.children)

    def _substitute(self, node):
        for key, value in node.attrs.items():
            if "$" in value:
                def lookup(match, node=node):
                    name = match.group(1)
                    if name not in self.params:
                        raise node.fail(f"unknown parameter ${name} (no <default name={name!r}>)")
                    return self.params[name]

                node.attrs[key] = _PARAMETER.sub(lookup, value)
        for child in node.children:
            self._substitute(child)

    def _expand(self, nodes, depth):
        out = []
        for node in nodes:
            if node.tag == "default":
                continue
            self._substitute(node)
            if node.tag == "include":
                if depth >= MAX_INCLUDES:
                    raise node.fail(f"includes nested more than {MAX_INCLUDES} deep")
                name = node.attrs.get("filename")
                if not name:
                    raise node.fail("needs a 'filename'")
                self.included += 1
                if self.included > MAX_INCLUDED:
                    raise node.fail(f"more than {MAX_INCLUDED} <include>s in all (a scene including files over and over)")
                included = _parse_xml(self.resolve(node, name))
                out += self._expand(included.children, depth + 1)
            else:
                out.append(node)
        return out

    def resolve(self, node, name):
        """A file a scene element names, relative to the scene's directory; InputError
        naming it, and every other file the scene names that is missing too."""
        path = self.base / name
        if path.exists() or path.is_symlink():  # there, but maybe not a file one can read (the input check says)
            try:
                check_input_file(path, "file")
            except InputError as exc:
                raise node.fail(str(exc)) from None
            return path
        if not path.is_file():
            others = [n for n in self._missing_files() if n != name]
            n = len(others)
            more = f" ({n} more file{'s' * (n > 1)} it names {'are' if n > 1 else 'is'} missing too: " \
                   f"{', '.join(others)})" if others else ""
            raise node.fail(f"file {str(path)!r} not found{more}")
        return path

    def _missing_files(self):
        """The ``filename`` properties of every element that name no file, in document order."""
        seen = []
        for node in self._walk(getattr(self, "elements", [])):  # none yet while includes are read
            name = node.attrs.get("value")
            if node.tag == "string" and node.attrs.get("name") == "filename" and name and name not in seen \
                    and not (self.base / name).is_file():
                seen.append(name)
        return seen

    def deref(self, node, tags):
        """``node`` itself, or the element its ``<ref id>`` names (one of ``tags``)."""
        if node.tag != "ref":
            return node
        ident = node.attrs.get("id")
        if not ident:
            raise node.fail("needs an 'id' (the element it refers to)")
        target = self.ids.get(ident)
        if target is None:
            raise node.fail(f"no element has id {ident!r}")
        if target.tag not in tags:
            raise node.fail(f"id {ident!r} is a <{target.tag}>, not a {' or '.join(f'<{t}>' for t in tags)}")
        return target


_OLD_TAGS = {"lookAt": "lookat"}  # Mitsuba 0.x's scene handler read both spellings as one tag


def _upgrade(nodes):
    """Mitsuba 0.x's spellings of tags in 2-3's, in place (as Mitsuba 3's own
    ``upgrade_tree`` does for property names)."""
    for node in nodes:
        node.tag = _OLD_TAGS.get(node.tag, node.tag)
        _upgrade(node.children)


def _major_version(root):
    text = root.attrs.get("version", "")
    match = re.match(r"\s*(\d+)\.(\d+)", text)
    if not match:
        if text:
            raise root.fail(f"version {text!r} is not a version number")
        return 3
    major, minor = int(match.group(1)), int(match.group(2))
    if major == 0 and minor < 4 or major > 3:
        raise root.fail(f"version {text} is not one this reader knows (0.4 to 0.6, 2 and 3)")
    return major
