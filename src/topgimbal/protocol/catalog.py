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

# `X as X`: re-exported names (PEP 484), so no list of them here to keep in step with the imports.
from .commands import GROUPS as GROUPS
from .commands import MANY_ROLES as MANY_ROLES
from .commands import ROLES as ROLES
from .commands import CommandSpec as CommandSpec
from .commands import factory_values as factory_values
from .commands import stored_form as stored_form
from .dialect import Dialect as Dialect
from .forms import QUERY as QUERY
from .forms import REQUEST as REQUEST
from .forms import RESPONSE as RESPONSE
from .forms import Form as Form
from .message import Message as Message
from .message import direction_of as direction_of
from .models import QUIRKS as QUIRKS
from .models import DeviceModel as DeviceModel
from .models import Endpoint as Endpoint
from .models import VideoStream as VideoStream
