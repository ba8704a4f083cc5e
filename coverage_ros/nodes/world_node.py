def main(args=None):
    print("temporary")
