"""The map and scenario editor: ``sgjax edit`` serves a page that draws a map, checks it with
:func:`sgjax.maps.check.check_map` on every edit, plays episodes of it and saves it
(docs/editor.md)."""

from sgjax.editor.session import EditorError, EditorSession

__all__ = ["EditorError", "EditorSession"]
