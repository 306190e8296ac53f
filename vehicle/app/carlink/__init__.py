"""The laptop's side of the car link: talk to a car's web server (pull tubs, push and switch pilots,
read its status), find cars on the network. Used by ``vehicle car`` and the console's Cars page."""
