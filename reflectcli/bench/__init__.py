"""`reflect bench`: technique x scene x parameter matrices against ray-traced references."""
