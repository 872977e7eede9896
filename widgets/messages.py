"""View > Messages: every message the status bar said, whole, selectable and copyable.

The status bar shows one message in one line, cut with an ellipsis when it is longer than the bar; a refusal's
reason or a file's path was then lost past the bar's edge (a first-use trial). The window keeps the recent
messages here, as ParaView's Output Messages and CloudCompare's console keep theirs; a click on the status bar's
message opens them.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Iterator
from dataclasses import dataclass

from qtpy import QtCore, QtGui, QtWidgets

#: Messages kept, the oldest dropped first.
KEPT_MESSAGES = 500
#: The size the log asks for, pixels (made to fit the screen by the window that opens it).
LOG_SIZE = (760, 360)
#: A refusal's or a failure's colour in the log, as in the status bar.
ERROR_COLOUR = "#d9534f"


@dataclass(frozen=True)
class Message:
    """One message as the status bar said it.

    Parameters
    ----------
    at : float
        When, seconds since the epoch.
    text : str
    error : bool
        A refusal or a failure (said red).
    """

    at: float
    text: str
    error: bool

    def line(self) -> str:
        """The message as the log writes it: its local time, then the text (``error:`` before a refusal's)."""
        mark = "error: " if self.error else ""
        return f"{time.strftime('%H:%M:%S', time.localtime(self.at))}  {mark}{self.text}"


class MessageLog:
    """The last ``kept`` messages, oldest first; a message said again right after itself is kept once."""

    def __init__(self, kept: int = KEPT_MESSAGES) -> None:
        self._messages: deque[Message] = deque(maxlen=kept)

    def add(self, text: str, error: bool = False, at: float | None = None) -> Message | None:
        """Keep ``text`` (unless it is empty or the last message again); the message kept, or None."""
        if not text or (self._messages and self._messages[-1].text == text
                        and self._messages[-1].error == error):
            return None
        message = Message(time.time() if at is None else at, text, error)
        self._messages.append(message)
        return message

    def __iter__(self) -> Iterator[Message]:
        return iter(self._messages)

    def __len__(self) -> int:
        return len(self._messages)

    def text(self) -> str:
        """Every message kept, one a line, oldest first."""
        return "\n".join(message.line() for message in self._messages)

    def clear(self) -> None:
        """Forget every message kept."""
        self._messages.clear()


class MessagesDialog(QtWidgets.QDialog):
    """The log in a read-only text box (select with the mouse, Ctrl+A, Ctrl+C), the newest at the bottom, with
    Copy all, Clear and Close; not modal, and kept up to date while it is open."""

    def __init__(self, log: MessageLog, parent: QtWidgets.QWidget | None = None) -> None:
        super().__init__(parent)
        self.setObjectName("messages")
        self.setWindowTitle("livox-viz - messages")
        self.log = log
        self.view = QtWidgets.QPlainTextEdit(self)
        self.view.setReadOnly(True)
        self.view.setLineWrapMode(QtWidgets.QPlainTextEdit.LineWrapMode.WidgetWidth)
        self.view.setTextInteractionFlags(QtCore.Qt.TextInteractionFlag.TextSelectableByMouse
                                          | QtCore.Qt.TextInteractionFlag.TextSelectableByKeyboard)
        buttons = QtWidgets.QDialogButtonBox(QtWidgets.QDialogButtonBox.StandardButton.Close, self)
        self.copy_button = buttons.addButton("Copy all", QtWidgets.QDialogButtonBox.ButtonRole.ActionRole)
        self.clear_button = buttons.addButton("Clear", QtWidgets.QDialogButtonBox.ButtonRole.ResetRole)
        self.copy_button.clicked.connect(self.copy_all)
        self.clear_button.clicked.connect(self.clear)
        buttons.rejected.connect(self.hide)
        layout = QtWidgets.QVBoxLayout(self)
        layout.addWidget(self.view)
        layout.addWidget(buttons)
        self.refill()

    def refill(self) -> None:
        """Show every message of the log, scrolled to the newest."""
        self.view.clear()
        for message in self.log:
            self.append(message)

    def append(self, message: Message) -> None:
        """One more message at the bottom (red for an error), scrolled to it."""
        cursor = QtGui.QTextCursor(self.view.document())
        cursor.movePosition(QtGui.QTextCursor.MoveOperation.End)
        if not self.view.document().isEmpty():
            cursor.insertBlock()
        words = QtGui.QTextCharFormat()
        if message.error:
            words.setForeground(QtGui.QColor(ERROR_COLOUR))
        cursor.insertText(message.line(), words)
        self.view.moveCursor(QtGui.QTextCursor.MoveOperation.End)
        self.view.ensureCursorVisible()

    def copy_all(self) -> None:
        """Every message, as plain text, to the clipboard."""
        QtWidgets.QApplication.clipboard().setText(self.log.text())

    def clear(self) -> None:
        """Forget the messages kept so far."""
        self.log.clear()
        self.view.clear()
