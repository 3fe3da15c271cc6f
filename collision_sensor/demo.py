"""Placeholder replaced below."""
def main():
    print('demo')
