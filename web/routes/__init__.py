"""One router per part of the API; :mod:`web.app` includes them all."""
