"""How many subscriptions a publisher has, kept from its matched events.

`Publisher.get_subscription_count` asks the middleware at each call (about 1 us, more
inside a running node), and a control cycle asks it of up to four publishers: whether
to send the command on `ft/command_raw` beside the call of ft-stack, the metrics, the
array command. rmw's publication-matched event carries the same count whenever a
subscription comes or goes, so an `Audience` keeps it for the cycle to read. The event
is taken by the node's executor, so a new subscriber is counted from the executor's
next turn on. A subscription's matched event counts its publishers the same way.
"""

from __future__ import annotations

from rclpy.event_handler import QoSPublisherMatchedInfo


class Audience:
    """The other ends matched to a publisher or a subscription (`SuiteNode`)."""

    def __init__(self) -> None:
        self.count = 0  #: matched other ends, as the last matched event said

    def matched(self, info: QoSPublisherMatchedInfo) -> None:
        """The matched event: another end came or went."""
        self.count = info.current_count
