"""Help > User guide: the pages of ``docs/`` in a browser beside the window.

The pages are the Markdown files of the repository's ``docs/`` (a checkout's, or the copy the wheel ships as
``livox_viz/shipped_docs``), shown as they are with Qt's own Markdown reader. A link to another page opens it in
the same browser (Back returns), a link to a heading (``window.md#keys``, named as GitHub names headings) scrolls
there, a web link opens in the system's browser, and a page this installation lacks (the README, beside a
checkout only) is said under the page instead of opening an empty one.
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

from qtpy import QtCore, QtGui, QtWidgets

#: The guide's first page: its contents.
INDEX = "index.md"
#: The size the guide asks for, pixels (made to fit the screen by the window that opens it).
GUIDE_SIZE = (980, 820)


def guide_dir() -> Path | None:
    """The folder of the guide's pages: ``docs/`` of a checkout, or the wheel's ``livox_viz/shipped_docs``; None
    when neither holds the index."""
    top = Path(__file__).resolve().parent.parent  # the checkout, or the installed livox_viz package
    for folder in (top / "docs", top / "shipped_docs"):
        if (folder / INDEX).is_file():
            return folder
    return None


def heading_anchor(text: str) -> str:
    """The anchor GitHub gives a heading: lower case, punctuation dropped, spaces as hyphens
    (``"What `scan` writes, and the ROS 2 bags"`` -> ``what-scan-writes-and-the-ros-2-bags``)."""
    return re.sub(r"[^\w\- ]", "", text.strip().lower()).replace(" ", "-")


class GuidePages(QtWidgets.QTextBrowser):
    """The browser of the guide's pages: a picture wider than the page is shown at the page's width (the
    screenshots are 1600 pixels wide)."""

    def loadResource(self, kind: int, url: QtCore.QUrl) -> Any:
        resource = super().loadResource(kind, url)
        if kind != QtGui.QTextDocument.ResourceType.ImageResource.value or resource is None:
            return resource
        image = resource if isinstance(resource, QtGui.QImage) else QtGui.QImage.fromData(resource)
        width = max(320, self.viewport().width() - 40)
        if image.isNull() or image.width() <= width:
            return image
        return image.scaledToWidth(width, QtCore.Qt.TransformationMode.SmoothTransformation)


class UserGuide(QtWidgets.QDialog):
    """The guide's pages in a :class:`QTextBrowser`, with Back, Contents and Close; not modal."""

    def __init__(self, folder: Path, parent: QtWidgets.QWidget | None = None) -> None:
        super().__init__(parent)
        self.setObjectName("user-guide")
        self.setWindowTitle("livox-viz - user guide")
        self.setModal(False)
        self.folder = folder
        self.browser = GuidePages(self)
        self.browser.setObjectName("guide-page")
        self.browser.setOpenLinks(False)  # every link goes through follow(): pages, headings, the web
        self.browser.anchorClicked.connect(self.follow)
        self.browser.sourceChanged.connect(self._scroll_to_heading)
        self.note = QtWidgets.QLabel(self)
        self.note.setObjectName("guide-note")
        buttons = QtWidgets.QDialogButtonBox(QtWidgets.QDialogButtonBox.StandardButton.Close, self)
        self.back = buttons.addButton("Back", QtWidgets.QDialogButtonBox.ButtonRole.ActionRole)
        self.back.setEnabled(False)
        self.back.clicked.connect(self.browser.backward)
        self.browser.backwardAvailable.connect(self.back.setEnabled)
        contents = buttons.addButton("Contents", QtWidgets.QDialogButtonBox.ButtonRole.ActionRole)
        contents.clicked.connect(self.home)
        buttons.rejected.connect(self.hide)
        layout = QtWidgets.QVBoxLayout(self)
        layout.addWidget(self.browser)
        layout.addWidget(self.note)
        layout.addWidget(buttons)
        self.home()

    def home(self) -> None:
        """Show the contents (``index.md``)."""
        self.follow(QtCore.QUrl.fromLocalFile(str(self.folder / INDEX)))

    def follow(self, url: QtCore.QUrl) -> None:
        """Open what a link names: a page of the guide here, a heading of the page shown, a web link outside."""
        self.note.clear()
        if url.scheme() in ("http", "https", "mailto"):
            QtGui.QDesktopServices.openUrl(url)
            return
        target = self.browser.source().resolved(url) if not self.browser.source().isEmpty() else url
        page = QtCore.QUrl(target)
        page.setFragment(None)
        shown = QtCore.QUrl(self.browser.source())
        shown.setFragment(None)
        if not shown.isEmpty() and page == shown:
            self._scroll_to_heading(target)
            return
        path = Path(page.toLocalFile())
        if not path.is_file():
            self.note.setText(f"{path.name} is not part of this installation of livox-viz")
            return
        if path.suffix.lower() != ".md":
            QtGui.QDesktopServices.openUrl(page)
            return
        self.browser.setSource(target, QtGui.QTextDocument.ResourceType.MarkdownResource)

    def _scroll_to_heading(self, url: QtCore.QUrl) -> None:
        """Bring the heading the URL's fragment names to the top (Qt's Markdown reader names no headings)."""
        fragment = url.fragment()
        if not fragment:
            return
        document = self.browser.document()
        block = document.begin()
        while block.isValid():
            if block.blockFormat().headingLevel() and heading_anchor(block.text()) == fragment:
                layout = self.browser.document().documentLayout()
                top = layout.blockBoundingRect(block).top()
                bar = self.browser.verticalScrollBar()
                # Qt brings the bar's range up to the page's height only as it lays the page out in the background:
                # a heading near the end of a long page (window.md's Keys) stopped short of the top.
                bar.setMaximum(max(bar.maximum(), math.ceil(layout.documentSize().height())
                                   - self.browser.viewport().height()))
                bar.setValue(int(top))
                return
            block = block.next()
