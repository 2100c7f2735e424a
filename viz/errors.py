"""Errors of the viewer (all derive from :class:`carmkin.CarmkinError`)."""

from carmkin.errors import CarmkinError


class VisualizationError(CarmkinError):
    """The viewer cannot do what was asked (no browser, no server, bad scene argument, ...)."""


class ServerError(VisualizationError):
    """The loopback meshcat server could not start or stop."""


class BrowserNotFoundError(VisualizationError):
    """No headless Chromium/Chrome executable to render a page with."""
