"""The catalog's building blocks, re-exported from the modules that define them (imports of
`topgimbal.protocol.catalog` keep working):

    forms.py     Form, REQUEST, RESPONSE, QUERY
    commands.py  CommandSpec, ROLES, GROUPS, factory_values
    models.py    DeviceModel (a model profile), Endpoint, VideoStream, QUIRKS
    message.py   Message, direction_of
    dialect.py   Dialect

A *command* (`CommandSpec`) is one identifier in one dialect. It has *forms*: the data layouts it
takes in each direction (`request` host -> device, `response` device -> host, which includes
unsolicited reports) and control (`r`/`w`). A *dialect* is an explicit object holding its commands
and device models; nothing here is global, two dialects live side by side.
"""

from __future__ import annotations

from .commands import GROUPS, MANY_ROLES, ROLES, CommandSpec, factory_values, stored_form
from .dialect import Dialect
from .forms import QUERY, REQUEST, RESPONSE, Form
from .message import Message, direction_of
from .models import QUIRKS, DeviceModel, Endpoint, VideoStream

__all__ = [
    "GROUPS",
    "MANY_ROLES",
    "QUERY",
    "QUIRKS",
    "REQUEST",
    "RESPONSE",
    "ROLES",
    "CommandSpec",
    "DeviceModel",
    "Dialect",
    "Endpoint",
    "Form",
    "Message",
    "VideoStream",
    "direction_of",
    "factory_values",
    "stored_form",
]
