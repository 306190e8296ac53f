"""The web controller and driver monitor: a browser page that drives the car (see docs/web.md).

Modules: ``controller`` (WebController, the threaded part), ``server`` (python-socketio on aiohttp),
``state`` (the lock-protected slot shared with the loop, dead-man rule), ``protocol`` (message
validation), ``pairing`` (token, URL, QR), ``arbiter`` (web page + gamepad). Nothing heavy is
imported here.
"""
