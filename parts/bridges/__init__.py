"""Simulator bridges: the Udacity simulator and the Donkey simulator as cars, and our simulator
served over the Donkey protocol.

- :mod:`parts.bridges.udacity_sim` – the Udacity simulator as a car (we are its Socket.IO server);
  :mod:`parts.bridges.engineio3` makes python-socketio 5 speak its Engine.IO v3 dialect;
  :mod:`parts.bridges.udacity_protocol` reads and writes its values (units, keys, locales).
- :mod:`parts.bridges.donkey_client` – the Donkey simulator as a car (we are its TCP client).
- :mod:`parts.bridges.donkey_server` – our simulator behind the Donkey protocol, for gym-donkeycar
  and any other Donkey-sim client.
- :mod:`parts.bridges.donkey_protocol` – framing, parsing and message tables shared by both sides.

The faithful fake peers the tests drive them with, written from docs/simulators.md's protocol
facts, live in tests/fixtures/ (fake_udacity_client.py, fake_donkey_sim.py, fake_road.py).

Nothing is imported here: each module imports what it needs when it is used.
"""
