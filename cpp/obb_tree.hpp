// obb_tree: see bindings.cpp. (placeholder until its port lands)
#pragma once
