// bounding_volumes: see bindings.cpp. (placeholder until its port lands)
#pragma once
