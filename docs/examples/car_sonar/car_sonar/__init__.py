"""An ultrasonic rangefinder (MaxBotix HRLV-MaxSonar, serial output) for vehicle-rc cars."""
